//! The board clock and the start strobe: TIM5, 32-bit, free-running at
//! 170 MHz, extended to 64 bits by counting its wraps (every 25.3 s).
//!
//! `now_ticks()` is board-core's time base. A scan starts on a TIM5 compare:
//! channel 1 in active-on-match mode raises OC1REF at exactly the requested
//! tick, OC1REF is TIM5's trigger output (TRGO), and TIM2 (edges) and TIM3
//! (feedback capture) start on it in slave trigger mode. No software sits
//! between the requested tick and the first edge. OC1 drives no pin.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::interrupt::typelevel::{Handler, Interrupt, TIM5 as Tim5Irq};
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::{Mms, Ocm, Urs};
use embassy_stm32::peripherals::TIM5;
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::Peri;

use crate::tick_extend::extend;

/// TIM2/TIM3 select TIM5's TRGO as ITR4 on the G4, whose internal trigger
/// table is the same for every slave (RM0440 "TIMx internal trigger
/// connection": ITR0 TIM1, ITR1 TIM2, ITR2 TIM3, ITR3 TIM4, ITR4 TIM5; ST's
/// G474 cascade example uses ITR1 = TIM2 for TIM3, and SimpleFOC's G4 timer
/// alignment maps master TIM5 to ITR4 for any slave).
pub const STROBE_TRIGGER: pac::timer::vals::Ts = pac::timer::vals::Ts::ITR4;
/// Ticks the CPU needs between the arming check and the compare (two
/// register writes inside a critical section): a start closer than this is
/// refused rather than fired late.
pub const MIN_START_LEAD_TICKS: u64 = 170; // 1 us

/// TIM5 wraps since boot: bits 32.. of the board clock.
static WRAPS: AtomicU32 = AtomicU32::new(0);

/// TIM5 as the 64-bit board clock and scan start strobe.
pub struct Timebase {
    tim: Timer<'static, TIM5>,
}

impl Timebase {
    /// Starts TIM5 free-running from 0 with its strobe output low.
    pub fn new(tim5: Peri<'static, TIM5>) -> Self {
        let tim = Timer::new(tim5);
        let r = tim.regs_gp32();
        r.cr1().modify(|w| {
            w.set_cen(false);
            w.set_urs(Urs::COUNTER_ONLY);
        });
        r.psc().write_value(0);
        r.arr().write_value(u32::MAX);
        r.egr().write(|w| w.set_ug(true)); // load PSC
        r.ccmr_output(0).modify(|w| {
            w.set_ocm(0, Ocm::FORCE_INACTIVE);
            w.set_ocpe(0, false);
        });
        r.cr2().modify(|w| w.set_mms(Mms::COMPARE_OC1)); // TRGO = OC1REF
        r.sr().write_value(pac::timer::regs::SrGp16(0));
        r.dier().modify(|w| w.set_uie(true));
        // Far from time-critical (one IRQ per 25 s), but must beat any
        // `now_ticks` reader by less than half a wrap: any priority does.
        Tim5Irq::set_priority(embassy_stm32::interrupt::Priority::P2);
        // SAFETY: `WrapIrq` is bound in board/g474/mod.rs; it touches only
        // TIM5's status register and `WRAPS`.
        unsafe { Tim5Irq::enable() };
        r.cr1().modify(|w| w.set_cen(true));
        Timebase { tim }
    }

    /// The board clock: TIM5 extended to 64 bits.
    pub fn now_ticks(&self) -> u64 {
        critical_section::with(|_| now_ticks_locked())
    }

    /// Lowers the strobe (TRGO) so the next compare is a rising edge.
    pub fn disarm_strobe(&mut self) {
        self.tim
            .regs_gp32()
            .ccmr_output(0)
            .modify(|w| w.set_ocm(0, Ocm::FORCE_INACTIVE));
    }

    /// Raises the strobe at board tick `at`: the slaves start counting on
    /// that tick. Refused (`Err(now)`) unless `at` is at least
    /// [`MIN_START_LEAD_TICKS`] ahead and within one TIM5 wrap.
    pub fn fire_strobe_at(&mut self, at: u64) -> Result<(), u64> {
        let r = self.tim.regs_gp32();
        critical_section::with(|_| {
            let now = now_ticks_locked();
            if at < now + MIN_START_LEAD_TICKS || at - now >= u64::from(u32::MAX) {
                return Err(now);
            }
            self.disarm_strobe();
            r.ccr(0).write_value(at as u32); // low 32 bits: TIM5 compares its CNT
            r.ccmr_output(0)
                .modify(|w| w.set_ocm(0, Ocm::ACTIVE_ON_MATCH));
            Ok(())
        })
    }
}

/// Board clock, interrupts already masked by the caller.
fn now_ticks_locked() -> u64 {
    let r = pac::TIM5;
    let wraps = WRAPS.load(Ordering::Relaxed);
    let cnt = r.cnt().read();
    // A wrap the IRQ has not counted yet shows as UIF (tick_extend.rs).
    extend(wraps, r.sr().read().uif(), cnt, 32)
}

/// Binds to TIM5's interrupt: counts wraps.
pub struct WrapIrq;

impl Handler<Tim5Irq> for WrapIrq {
    unsafe fn on_interrupt() {
        let r = pac::TIM5;
        if r.sr().read().uif() {
            // rc_w0: clear UIF only.
            r.sr().write_value(pac::timer::regs::SrGp16(!1));
            WRAPS.fetch_add(1, Ordering::Relaxed);
        }
    }
}
