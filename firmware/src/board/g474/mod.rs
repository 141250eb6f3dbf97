//! NUCLEO-G474RE (STM32G474RE): clocks, pin table, timers, capture, USB.
//!
//! [`init`] is the only entry point: it brings up the clock tree, takes each
//! peripheral once (pins.rs), puts every trigger output at its inactive
//! level and hands back owned drivers for `main.rs` to move into tasks.

pub mod capture;
pub mod clocks;
pub mod hardware;
pub mod pins;
pub mod timebase;
pub mod timers;

use embassy_stm32::gpio::{Level, Output, Speed};
use embassy_stm32::peripherals::{IWDG, USB};
use embassy_stm32::usb::Driver;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, interrupt, pac, peripherals, usb};
use protocol::ResetCause;

use self::capture::FeedbackCapture;
use self::hardware::G474Hardware;
use self::pins::Pins;
use self::timebase::Timebase;
use self::timers::{DmaBuffers, TriggerTimers};

bind_interrupts!(
    /// Interrupts the firmware handles; everything else stays disabled.
    pub struct Irqs {
        USB_LP => usb::InterruptHandler<peripherals::USB>;
        TIM2 => timers::CycleIrq;
        TIM3 => capture::CaptureIrq;
        TIM5 => timebase::WrapIrq;
    }
);

/// Independent watchdog timeout: a stalled executor resets the board
/// within this; the outputs then float to their pull-resistor idle level.
pub const WATCHDOG_TIMEOUT_US: u32 = 500_000;

/// Reads and clears the RCC_CSR reset flags: why the MCU last reset, in
/// the protocol's terms (reported to the host in `DeviceInfo`). Call before
/// anything else could reset them.
fn take_reset_cause() -> ResetCause {
    let csr = pac::RCC.csr().read();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    defmt::info!(
        "reset flags: iwdg={} sw={} pin={} bor={} wwdg={} lpwr={} obl={}",
        csr.iwdgrstf(),
        csr.sftrstf(),
        csr.pinrstf(),
        csr.borrstf(),
        csr.wwdgrstf(),
        csr.lpwrrstf(),
        csr.oblrstf()
    );
    if csr.iwdgrstf() {
        ResetCause::Watchdog
    } else if csr.sftrstf() && !csr.borrstf() {
        ResetCause::Software
    } else {
        // Power-on, brown-out, the reset pin (button, probe) and the rarer
        // causes all start from a clean slate: `PowerOn`.
        ResetCause::PowerOn
    }
}

/// The owned drivers of the board.
pub struct Board {
    /// Trigger timers, board clock and feedback capture (board-core's hardware).
    pub hardware: G474Hardware,
    /// USB full-speed device driver.
    pub usb: Driver<'static, USB>,
    /// Status LED LD2 (PA5).
    pub led: Output<'static>,
    /// Independent watchdog, not yet started.
    pub watchdog: IndependentWatchdog<'static, IWDG>,
    /// Why the board last reset.
    pub reset_cause: ResetCause,
    /// 64-bit hash of the MCU's 96-bit unique id.
    pub board_id: u64,
}

/// Brings the board up. `buffers` are the trigger DMA buffers (a static:
/// 20 KiB do not belong on a stack).
pub fn init(buffers: &'static mut DmaBuffers) -> Board {
    let reset_cause = take_reset_cause();
    let p = embassy_stm32::init(clocks::config());
    // Keep the watchdog and trigger timers still while a debugger halts the
    // core, so a breakpoint neither resets the board nor plays half a scan.
    pac::DBGMCU.apb1lfzr().modify(|w| {
        w.set_iwdg(true);
        w.set_tim2(true);
        w.set_tim3(true);
        w.set_tim5(true);
    });
    let pins = Pins::take(p);
    let timers = TriggerTimers::new(pins.trigger, buffers);
    let capture = FeedbackCapture::new(pins.feedback);
    let timebase = Timebase::new(pins.timebase);
    let hardware = G474Hardware::new(timebase, timers, capture);
    let usb = Driver::new(pins.usb.usb, Irqs, pins.usb.dp, pins.usb.dm);
    // Below the timer IRQs (P1): a USB transfer must not delay a capture or
    // the cycle check. (The driver enables its IRQ at the default P0.)
    <interrupt::typelevel::USB_LP as interrupt::typelevel::Interrupt>::set_priority(
        interrupt::Priority::P2,
    );
    let led = Output::new(pins.led, Level::Low, Speed::Low);
    let watchdog = IndependentWatchdog::new(pins.iwdg, WATCHDOG_TIMEOUT_US);
    defmt::info!(
        "board: NUCLEO-G474RE up, last reset: {}",
        defmt::Debug2Format(&reset_cause)
    );
    Board {
        hardware,
        usb,
        led,
        watchdog,
        reset_cause,
        board_id: board_id(),
    }
}

/// Any fault (and every panic: panic-probe logs it, then raises a
/// HardFault) first forces every trigger output inactive, so a scan does
/// not keep playing while the watchdog runs out; then the watchdog resets
/// the board within `WATCHDOG_TIMEOUT_US`. (Under `probe-rs run` the
/// debugger halts on the fault before this runs.)
#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    timers::stop_outputs();
    loop {
        cortex_m::asm::nop();
    }
}

/// FNV-1a of the 96-bit unique id: stable per chip, fits `DeviceInfo::board_id`.
fn board_id() -> u64 {
    embassy_stm32::uid::uid()
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
            (h ^ u64::from(*b)).wrapping_mul(0x0000_0100_0000_01b3)
        })
}
