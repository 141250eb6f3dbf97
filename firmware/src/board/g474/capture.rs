//! Feedback timestamps: TIM3 input capture of the projectors' trigger-out
//! and the cameras' exposure-active lines, on the trigger timer's time base.
//!
//! TIM3 counts the same 170 MHz clock as TIM2 and starts on the same strobe
//! edge (timebase.rs), so a capture is "ticks since the strobe"; TIM3 is
//! 16-bit, so its IRQ extends each capture with a software count of TIM3
//! wraps (every 385 us). Both edges are captured; the level after an edge is
//! tracked by alternation from the idle level read at arm time, and an
//! over-capture (a second edge before the IRQ read the first) is reported
//! and resynchronises the level from the pin.

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt::typelevel::{Handler, Interrupt, TIM3 as Tim3Irq};
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::{CcmrInputCcs, FilterValue, Sms};
use embassy_stm32::peripherals::TIM3;
use embassy_stm32::timer::input_capture::CapturePin;
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::timer::{Ch1, Ch2, Ch3, Ch4};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;

use super::pins::{FeedbackPins, FEEDBACK_CHANNELS, FEEDBACK_PIN_NUMBERS};
use super::timebase::STROBE_TRIGGER;
use crate::tick_extend::extend;

/// Captures buffered between the IRQ and the sequencer task (16 B each):
/// the seed-001 plan makes ~11 feedback edges per ms, so this covers ~23 ms
/// of the link task being busy (a burst of USB writes takes a few ms).
pub const CAPTURE_QUEUE_LEN: usize = 256;

/// One feedback edge as the IRQ saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct RawCapture {
    /// Feedback channel (TIM3 CH1 = 0).
    pub channel: u8,
    /// Timer ticks (170 MHz) since the start strobe.
    pub ticks_since_strobe: u64,
    /// Line level after the edge (true = high).
    pub level_high: bool,
    /// An earlier edge on this channel was lost (over-capture) or dropped
    /// (queue full) since the previous reported capture.
    pub lost_before: bool,
}

static CAPTURES: Channel<CriticalSectionRawMutex, RawCapture, CAPTURE_QUEUE_LEN> = Channel::new();
/// TIM3 wraps since the strobe: the high bits of every capture.
static WRAPS: AtomicU32 = AtomicU32::new(0);
/// Level after the last edge, per channel.
static LEVEL: [AtomicBool; FEEDBACK_CHANNELS] =
    [const { AtomicBool::new(false) }; FEEDBACK_CHANNELS];
/// An edge was lost on this channel and not yet reported.
static LOST: [AtomicBool; FEEDBACK_CHANNELS] =
    [const { AtomicBool::new(false) }; FEEDBACK_CHANNELS];

/// Input filter: 8 samples at 170 MHz must agree (47 ns): rejects ringing on
/// long camera cables, far below any real pulse width.
const INPUT_FILTER: FilterValue = FilterValue::FCK_INT_N8;

/// TIM3 capture of the four feedback lines.
pub struct FeedbackCapture {
    tim: Timer<'static, TIM3>,
    _pins: CapturePins,
}

/// The four feedback pins in timer-input mode, held for the driver's life.
type CapturePins = (
    CapturePin<'static, TIM3, Ch1>,
    CapturePin<'static, TIM3, Ch2>,
    CapturePin<'static, TIM3, Ch3>,
    CapturePin<'static, TIM3, Ch4>,
);

impl FeedbackCapture {
    /// Configures TIM3 as a slave of the start strobe with all four channels
    /// capturing both edges. Lines float to their idle level through the
    /// README's pull resistors; the pins get a weak pull-down as a backstop.
    pub fn new(pins: FeedbackPins) -> Self {
        let tim = Timer::new(pins.timer);
        let r = tim.regs_gp16();
        r.cr1().modify(|w| w.set_cen(false));
        r.psc().write_value(0);
        r.arr().write(|w| w.set_arr(0xFFFF));
        for ch in 0..FEEDBACK_CHANNELS {
            r.ccmr_input(ch / 2).modify(|w| {
                // CCxS = 01: ICx on its own pin TIx (the PAC calls this value `TI4`).
                w.set_ccs(ch % 2, CcmrInputCcs::TI4);
                w.set_icf(ch % 2, INPUT_FILTER);
            });
            r.ccer().modify(|w| {
                w.set_ccp(ch, true); // CCxP = CCxNP = 1: both edges
                w.set_ccnp(ch, true);
                w.set_cce(ch, true);
            });
        }
        r.smcr().modify(|w| {
            w.set_ts(STROBE_TRIGGER);
            w.set_sms(Sms::TRIGGER_MODE);
        });
        let pins_af = (
            CapturePin::new(pins.in0, Pull::Down),
            CapturePin::new(pins.in1, Pull::Down),
            CapturePin::new(pins.in2, Pull::Down),
            CapturePin::new(pins.in3, Pull::Down),
        );
        // Must be served within half a TIM3 period (193 us) to extend
        // captures correctly; same level as the cycle IRQ, above USB.
        Tim3Irq::set_priority(embassy_stm32::interrupt::Priority::P1);
        // SAFETY: `CaptureIrq` is bound in board/g474/mod.rs and touches only
        // TIM3 registers and this file's statics.
        unsafe { Tim3Irq::enable() };
        FeedbackCapture {
            tim,
            _pins: pins_af,
        }
    }

    /// Re-arms for a new scan: counter stopped at 0 waiting for the strobe,
    /// levels taken from the pins now, stale captures dropped, capture
    /// interrupts on. Edges between scans are not captured at all.
    pub fn arm(&mut self) {
        let r = self.tim.regs_gp16();
        self.stop();
        r.cnt().write(|w| w.set_cnt(0));
        r.sr().write_value(pac::timer::regs::SrGp16(0));
        WRAPS.store(0, Ordering::Relaxed);
        let idr = pac::GPIOC.idr().read();
        for (ch, pin) in FEEDBACK_PIN_NUMBERS.into_iter().enumerate() {
            LEVEL[ch].store(
                idr.idr(pin) == pac::gpio::vals::Idr::HIGH,
                Ordering::Relaxed,
            );
            LOST[ch].store(false, Ordering::Relaxed);
        }
        CAPTURES.clear();
        r.dier().modify(|w| {
            w.set_uie(true);
            for ch in 0..FEEDBACK_CHANNELS {
                w.set_ccie(ch, true);
            }
        });
    }

    /// Stops the capture counter and its interrupts (after a scan).
    pub fn stop(&mut self) {
        let r = self.tim.regs_gp16();
        r.dier().modify(|w| {
            w.set_uie(false);
            for ch in 0..FEEDBACK_CHANNELS {
                w.set_ccie(ch, false);
            }
        });
        r.cr1().modify(|w| w.set_cen(false));
    }

    /// The next capture: first serves the capture flags (so every edge up to
    /// now is readable even if the IRQ has not run yet), then pops the queue.
    pub fn pop(&mut self) -> Option<RawCapture> {
        // SAFETY: the same body the IRQ runs, with interrupts masked so the
        // two cannot interleave.
        critical_section::with(|_| unsafe { CaptureIrq::on_interrupt() });
        CAPTURES.try_receive().ok()
    }
}

/// The current level of feedback pin `ch` (GPIOC input data register).
fn pin_is_high(ch: usize) -> bool {
    pac::GPIOC.idr().read().idr(FEEDBACK_PIN_NUMBERS[ch]) == pac::gpio::vals::Idr::HIGH
}

/// Binds to TIM3's interrupt: reads captures, extends them to 64 bits.
pub struct CaptureIrq;

impl Handler<Tim3Irq> for CaptureIrq {
    unsafe fn on_interrupt() {
        let r = pac::TIM3;
        let sr = r.sr().read();
        let wraps = WRAPS.load(Ordering::Relaxed);
        for ch in 0..FEEDBACK_CHANNELS {
            if !sr.ccif(ch) {
                continue;
            }
            let lost = sr.ccof(ch);
            let low = r.ccr(ch).read().ccr(); // reading CCRx clears CCxIF
                                              // Each capture flips the level, except after an over-capture:
                                              // an unknown number of edges went by and CCRx holds the latest,
                                              // so the pin, read microseconds later, tells its level.
            let level = if lost {
                pin_is_high(ch)
            } else {
                !LEVEL[ch].load(Ordering::Relaxed)
            };
            LEVEL[ch].store(level, Ordering::Relaxed);
            let cap = RawCapture {
                channel: ch as u8,
                // A wrap pending in this pass is counted below; captures
                // latched after it carry it already (tick_extend.rs).
                ticks_since_strobe: extend(wraps, sr.uif(), u32::from(low), 16),
                level_high: level,
                lost_before: lost || LOST[ch].load(Ordering::Relaxed),
            };
            if CAPTURES.try_send(cap).is_ok() {
                LOST[ch].store(false, Ordering::Relaxed);
            } else {
                LOST[ch].store(true, Ordering::Relaxed);
            }
        }
        // Clear what we handled (rc_w0: 0 clears, 1 leaves alone): UIF if it
        // was part of this pass, and every over-capture flag we reported.
        let mut clear = !0u32;
        if sr.uif() {
            clear &= !1;
            WRAPS.store(wraps + 1, Ordering::Relaxed);
        }
        for ch in 0..FEEDBACK_CHANNELS {
            if sr.ccof(ch) {
                clear &= !(1 << (9 + ch));
            }
        }
        r.sr().write_value(pac::timer::regs::SrGp16(clear));
    }
}
