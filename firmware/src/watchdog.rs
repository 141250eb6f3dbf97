//! The independent watchdog: pet from a low-priority task, so a stalled
//! executor (a task that never yields, a deadlock, a fault loop) resets the
//! board within `WATCHDOG_TIMEOUT_US`. After that reset the trigger pins
//! float and the external pull resistors hold every line inactive
//! (README.md "Safe state"); the host sees the USB device vanish, and the
//! boot log names the cause.

use embassy_stm32::peripherals::IWDG;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_time::Timer;

/// Pet period: a fifth of the 500 ms timeout.
const PET_PERIOD_MS: u64 = 100;

/// Starts the watchdog and pets it forever.
#[embassy_executor::task]
pub async fn run(mut wdg: IndependentWatchdog<'static, IWDG>) {
    wdg.unleash();
    defmt::info!("watchdog: running");
    loop {
        wdg.pet();
        Timer::after_millis(PET_PERIOD_MS).await;
    }
}
