//! Trigger outputs on hardware timing: TIM2 output compare fed by DMA.
//!
//! ```text
//!             DMA1_CHk (circular, memory -> TIM2_CCRk, request = CCk match)
//! words[k] ───────────────────────────────┐
//!                                         v
//! TIM5 OC1REF ─TRGO─> TIM2 (32 bit, 170 MHz, ARR = period - 1) ──CNT == CCRk──> OCk toggles ──> pin
//! (timebase.rs)  └──> TIM3 (feedback capture, capture.rs): same start edge, same clock
//! ```
//!
//! Every edge is a compare match of the counter: the pin toggles on the
//! timer clock edge where `CNT == CCRk` (5.88 ns resolution at 170 MHz, no
//! software in the path), and the same match asks the channel's DMA to
//! write the next compare value into `CCRk` (preload off, so the write takes
//! effect at once). Software only loads the tables and arms the strobe.
//!
//! One cycle of the plan is one counter period (ARR = period - 1), so the
//! circular DMA replays the same per-cycle words for every repetition
//! (layout: ../../dma_table.rs); the update interrupt counts cycles and sets
//! one-pulse mode during the last one, which stops the counter in hardware
//! when the last cycle ends.
//!
//! Why the PAC for the DMA: embassy's `Transfer` lives as long as a borrow of
//! its buffer and is meant to be awaited to completion, while this table
//! replays circularly until the hardware stops and must outlive the call that
//! started it. Programming the four DMA1 channels directly is thirty lines and
//! keeps the whole path visible here.

use core::sync::atomic::{AtomicU32, AtomicU8, Ordering};

use board_core::EdgeTable;
use embassy_stm32::gpio::OutputType;
use embassy_stm32::interrupt::typelevel::{Handler, Interrupt, TIM2 as Tim2Irq};
use embassy_stm32::pac;
use embassy_stm32::pac::bdma::vals::{Dir, Pl, Size};
use embassy_stm32::pac::timer::vals::{Ocm, Sms, Urs};
use embassy_stm32::peripherals::{DMA1_CH1, DMA1_CH2, DMA1_CH3, DMA1_CH4, TIM2};
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::timer::{Ch1, Ch2, Ch3, Ch4};
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use protocol::HardwareFault;

use super::pins::{
    TriggerPins, TIM2_CC_DMA_REQUEST, TRIGGER_ACTIVE_HIGH, TRIGGER_CHANNELS, TRIGGER_DMA_CHANNEL,
};
use super::timebase::STROBE_TRIGGER;
use crate::dma_table::{check_channels, counter_shift, fill_channel, ChannelLayout};

/// Words one output channel's DMA buffer holds. Validation gives a channel
/// to one device of one head, so it carries at most a projector's edges for
/// every slot of the cycle (`protocol::limits::MAX_EDGES_PER_CHANNEL`, 2 KiB
/// of words), not the plan-wide cap `MAX_EDGES`, which grows with the heads
/// a plan may have (4 x 2 KiB here instead of 4 x 10 KiB); `load` still
/// refuses a table over it with `HardwareFault::TableTooLarge`.
pub const MAX_EDGES_PER_CHANNEL: usize = protocol::limits::MAX_EDGES_PER_CHANNEL;

/// The DMA buffers, one per output channel.
pub type DmaBuffers = [[u32; MAX_EDGES_PER_CHANNEL]; TRIGGER_CHANNELS];

/// Cycles completed in the running scan (written by the TIM2 update IRQ).
static CYCLES_DONE: AtomicU32 = AtomicU32::new(0);
/// Cycles the running scan must complete.
static REPEAT_COUNT: AtomicU32 = AtomicU32::new(0);
/// First compare value and edge count per channel, for the IRQ's check.
static FIRST_COMPARE: [AtomicU32; TRIGGER_CHANNELS] =
    [const { AtomicU32::new(0) }; TRIGGER_CHANNELS];
static EDGE_COUNT: [AtomicU32; TRIGGER_CHANNELS] = [const { AtomicU32::new(0) }; TRIGGER_CHANNELS];
/// `NO_FAULT`, or the channel whose DMA fell behind (the IRQ stopped the scan).
static UNDERRUN: AtomicU8 = AtomicU8::new(NO_FAULT);
const NO_FAULT: u8 = 0xFF;
/// Woken at the end of every cycle and when the IRQ stopped a scan.
static CYCLE_EVENT: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// What the trigger timer is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum RunState {
    /// Nothing loaded, or stopped.
    Idle,
    /// Words are in the DMA buffers; `arm` prepares a start.
    Loaded,
    /// Waiting for the strobe, counting, or stopped by itself after the
    /// last cycle (until `stop`).
    Running,
}

/// The four trigger pins in timer-output mode, held for the driver's life.
type OutputPins = (
    PwmPin<'static, TIM2, Ch1>,
    PwmPin<'static, TIM2, Ch2>,
    PwmPin<'static, TIM2, Ch3>,
    PwmPin<'static, TIM2, Ch4>,
);
/// The DMA channels feeding CCR1..CCR4, reserved so nothing else uses them.
type TriggerDma = (
    Peri<'static, DMA1_CH1>,
    Peri<'static, DMA1_CH2>,
    Peri<'static, DMA1_CH3>,
    Peri<'static, DMA1_CH4>,
);

/// TIM2 + DMA1 trigger outputs.
pub struct TriggerTimers {
    tim: Timer<'static, TIM2>,
    _pins: OutputPins,
    _dma: TriggerDma,
    buffers: &'static mut DmaBuffers,
    layout: [ChannelLayout; TRIGGER_CHANNELS],
    period_ticks: u32,
    shift_ticks: u32,
    state: RunState,
}

impl TriggerTimers {
    /// Configures TIM2 with every output forced to its inactive level, and
    /// only then hands the pins to the timer, so no output ever glitches
    /// active (before this the pins float and the README's pull resistors
    /// hold them inactive).
    pub fn new(pins: TriggerPins, buffers: &'static mut DmaBuffers) -> Self {
        let tim = Timer::new(pins.timer);
        let r = tim.regs_gp32();
        r.cr1().modify(|w| {
            w.set_cen(false);
            w.set_urs(Urs::COUNTER_ONLY); // only the wrap raises UIF, not UG
            w.set_arpe(false); // ARR written while stopped, no preload needed
        });
        r.psc().write_value(0); // count at the full 170 MHz
        r.smcr().modify(|w| {
            w.set_ts(STROBE_TRIGGER);
            w.set_sms(Sms::TRIGGER_MODE);
        });
        for (ch, active_high) in TRIGGER_ACTIVE_HIGH.into_iter().enumerate() {
            force_inactive(ch);
            r.ccmr_output(ch / 2).modify(|w| w.set_ocpe(ch % 2, false));
            r.ccer().modify(|w| {
                // CCxP inverts OCx: an active-low line idles high.
                w.set_ccp(ch, !active_high);
                w.set_cce(ch, true);
            });
        }
        // The forced levels reach the pins only now, through the AF switch.
        let pins_af = (
            PwmPin::new(pins.out0, OutputType::PushPull),
            PwmPin::new(pins.out1, OutputType::PushPull),
            PwmPin::new(pins.out2, OutputType::PushPull),
            PwmPin::new(pins.out3, OutputType::PushPull),
        );
        // The cycle IRQ outranks USB and the executor: its per-cycle check
        // should run before the next cycle's first edge.
        Tim2Irq::set_priority(embassy_stm32::interrupt::Priority::P1);
        // SAFETY: the handler (`CycleIrq`) is bound in board/g474/mod.rs and
        // touches only TIM2/DMA1 registers and this file's atomics.
        unsafe { Tim2Irq::enable() };
        defmt::info!("trigger timers: TIM2 at 170 MHz, outputs forced inactive");
        TriggerTimers {
            tim,
            _pins: pins_af,
            _dma: pins.dma,
            buffers,
            layout: [ChannelLayout {
                first_compare: 0,
                edge_count: 0,
            }; TRIGGER_CHANNELS],
            period_ticks: 0,
            shift_ticks: 0,
            state: RunState::Idle,
        }
    }

    /// Lays `table` out into the DMA buffers (dma_table.rs). Outputs stay
    /// inactive. On error nothing is loaded.
    pub fn load(&mut self, table: &EdgeTable) -> Result<(), HardwareFault> {
        self.stop();
        self.state = RunState::Idle;
        check_channels(table, TRIGGER_CHANNELS as u8, MAX_EDGES_PER_CHANNEL)?;
        let shift = counter_shift(table)?;
        for ch in 0..TRIGGER_CHANNELS {
            self.layout[ch] = fill_channel(table, ch as u8, shift, &mut self.buffers[ch])?;
        }
        self.period_ticks = table.period_ticks();
        self.shift_ticks = shift;
        self.state = RunState::Loaded;
        defmt::info!(
            "trigger timers: loaded period={=u32} shift={=u32} ticks, edges/channel {=u16} {=u16} {=u16} {=u16}",
            self.period_ticks,
            shift,
            self.layout[0].edge_count,
            self.layout[1].edge_count,
            self.layout[2].edge_count,
            self.layout[3].edge_count
        );
        Ok(())
    }

    /// Ticks the counter runs before the plan's cycle start (dma_table.rs):
    /// the strobe must fire this much before `start_tick`.
    pub fn shift_ticks(&self) -> u32 {
        self.shift_ticks
    }

    /// Arms the DMA and compares for `repeat_count` cycles; the counter
    /// starts on the next strobe. Returns false unless a table is loaded.
    pub fn arm(&mut self, repeat_count: u32) -> bool {
        if self.state != RunState::Loaded || repeat_count == 0 || self.period_ticks == 0 {
            return false;
        }
        let r = self.tim.regs_gp32();
        r.cr1().modify(|w| {
            w.set_cen(false);
            // The counter stops itself at the end of the last cycle; for
            // longer scans the IRQ sets OPM during the last cycle.
            w.set_opm(repeat_count == 1);
        });
        r.arr().write_value(self.period_ticks - 1);
        r.egr().write(|w| w.set_ug(true)); // load PSC, CNT = 0; URS keeps UIF clear
        r.cnt().write_value(0);
        r.sr().write_value(pac::timer::regs::SrGp16(0)); // drop stale flags
        CYCLES_DONE.store(0, Ordering::Relaxed);
        REPEAT_COUNT.store(repeat_count, Ordering::Relaxed);
        UNDERRUN.store(NO_FAULT, Ordering::Relaxed);
        CYCLE_EVENT.reset();
        for ch in 0..TRIGGER_CHANNELS {
            let ChannelLayout {
                first_compare,
                edge_count,
            } = self.layout[ch];
            FIRST_COMPARE[ch].store(first_compare, Ordering::Relaxed);
            EDGE_COUNT[ch].store(u32::from(edge_count), Ordering::Relaxed);
            if edge_count == 0 {
                continue; // stays forced inactive
            }
            r.ccr(ch).write_value(first_compare);
            arm_dma(ch, &self.buffers[ch][..usize::from(edge_count)]);
            r.dier().modify(|w| w.set_ccde(ch, true));
            // Toggle mode starts from the forced-low OCxREF: the first match
            // is the rising (active) edge.
            r.ccmr_output(ch / 2)
                .modify(|w| w.set_ocm(ch % 2, Ocm::TOGGLE));
        }
        r.dier().modify(|w| w.set_uie(true));
        self.state = RunState::Running;
        true
    }

    /// The channel whose DMA fell behind its compares, if any: checked by the
    /// IRQ after every cycle and here once the last cycle has ended (every
    /// circular DMA must be back at its full count, without a transfer
    /// error).
    pub fn underrun(&self) -> Option<u8> {
        let flagged = UNDERRUN.load(Ordering::Acquire);
        if flagged != NO_FAULT {
            return Some(flagged);
        }
        let finished = self.state == RunState::Running
            && CYCLES_DONE.load(Ordering::Acquire) >= REPEAT_COUNT.load(Ordering::Relaxed);
        if !finished {
            return None;
        }
        let isr = pac::DMA1.isr().read();
        (0..TRIGGER_CHANNELS).find_map(|ch| {
            let n = self.layout[ch].edge_count;
            let d = TRIGGER_DMA_CHANNEL[ch];
            let left = pac::DMA1.ch(d).ndtr().read().ndt();
            (n != 0 && (left != n || isr.teif(d))).then_some(ch as u8)
        })
    }

    /// Waits (without spinning) for the next cycle end or IRQ stop.
    pub async fn wait_cycle(&self) {
        CYCLE_EVENT.wait().await;
    }

    /// Stops the counter and DMA and forces every output inactive, now.
    /// Safe in any state; the loaded words stay for a new `arm`.
    pub fn stop(&mut self) {
        critical_section::with(|_| stop_outputs());
        if self.state == RunState::Running {
            self.state = RunState::Loaded;
        }
    }
}

/// Binds to TIM2's interrupt: counts cycles, stops the last one in
/// hardware, checks each cycle that no channel's DMA fell behind.
pub struct CycleIrq;

impl Handler<Tim2Irq> for CycleIrq {
    unsafe fn on_interrupt() {
        let r = pac::TIM2;
        if !r.sr().read().uif() {
            return;
        }
        // rc_w0 flags: write 0 to UIF only, 1 (no effect) to the rest.
        r.sr().write_value(pac::timer::regs::SrGp16(!1));
        let done = CYCLES_DONE.load(Ordering::Relaxed) + 1;
        // A full cycle leaves every circular DMA at its full count. Checked
        // only while the counter is still before the channel's first edge
        // of the new cycle (a late IRQ skips; `underrun` checks at the end).
        let cnt = r.cnt().read();
        for ch in 0..TRIGGER_CHANNELS {
            let n = EDGE_COUNT[ch].load(Ordering::Relaxed);
            if n == 0 || cnt >= FIRST_COMPARE[ch].load(Ordering::Relaxed) {
                continue;
            }
            let left = pac::DMA1.ch(TRIGGER_DMA_CHANNEL[ch]).ndtr().read().ndt();
            if u32::from(left) != n {
                stop_outputs();
                UNDERRUN.store(ch as u8, Ordering::Release);
                CYCLE_EVENT.signal(());
                return;
            }
        }
        if done + 1 == REPEAT_COUNT.load(Ordering::Relaxed) {
            // The last cycle is running: stop the counter at its end.
            r.cr1().modify(|w| w.set_opm(true));
        }
        CYCLES_DONE.store(done, Ordering::Release);
        CYCLE_EVENT.signal(());
    }
}

/// Channel `ch`'s compare output to forced inactive (OCxREF low).
fn force_inactive(ch: usize) {
    pac::TIM2
        .ccmr_output(ch / 2)
        .modify(|w| w.set_ocm(ch % 2, Ocm::FORCE_INACTIVE));
}

/// All outputs inactive, counter stopped, DMA requests and channels off.
/// Register-only so the IRQ and the fault handler can call it too; callers
/// in thread mode hold a critical section so the IRQ's OPM write cannot
/// interleave.
pub(super) fn stop_outputs() {
    let r = pac::TIM2;
    // Outputs first: from here on no compare can move a pin.
    for ch in 0..TRIGGER_CHANNELS {
        force_inactive(ch);
    }
    r.cr1().modify(|w| w.set_cen(false));
    r.dier().modify(|w| {
        w.set_uie(false);
        for ch in 0..TRIGGER_CHANNELS {
            w.set_ccde(ch, false);
        }
    });
    for d in TRIGGER_DMA_CHANNEL {
        pac::DMA1.ch(d).cr().modify(|w| w.set_en(false));
    }
}

/// Programs the DMA1 channel of trigger channel `ch`: circular, memory ->
/// TIM2_CCRch, one 32-bit word per CCch request.
fn arm_dma(ch: usize, words: &[u32]) {
    let d = TRIGGER_DMA_CHANNEL[ch];
    let c = pac::DMA1.ch(d);
    c.cr().modify(|w| w.set_en(false));
    pac::DMA1.ifcr().write(|w| w.set_gif(d, true));
    pac::DMAMUX1.ccr(d).write(|w| {
        w.set_dmareq_id(TIM2_CC_DMA_REQUEST[ch]);
        w.set_nbreq(0);
    });
    c.par().write_value(pac::TIM2.ccr(ch).as_ptr() as u32);
    c.mar().write_value(words.as_ptr() as u32);
    c.ndtr().write(|w| w.set_ndt(words.len() as u16));
    c.cr().write(|w| {
        w.set_dir(Dir::FROM_MEMORY);
        w.set_msize(Size::BITS32);
        w.set_psize(Size::BITS32);
        w.set_minc(true);
        w.set_pinc(false);
        w.set_circ(true);
        w.set_pl(Pl::VERY_HIGH); // trigger edges outrank anything else on DMA1
        w.set_en(true);
    });
}
