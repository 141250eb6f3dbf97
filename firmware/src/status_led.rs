//! The status LED (LD2) shows the sequencer state at a glance.
//!
//! | state            | LED                              |
//! |------------------|----------------------------------|
//! | idle, no host    | 1 Hz blink, short flash          |
//! | armed            | on                               |
//! | running          | 10 Hz blink                      |
//! | done / aborted   | 1 Hz blink, long on              |
//! | faulted          | double flash every second        |

use embassy_stm32::gpio::Output;
use embassy_time::Timer;
use protocol::ScanState;

use crate::usb_link::scan_state;

/// On/off phases of one 1-second LED period, in 50 ms steps.
fn pattern(state: ScanState) -> &'static [bool; 20] {
    const IDLE: [bool; 20] = {
        let mut p = [false; 20];
        p[0] = true;
        p
    };
    const ON: [bool; 20] = [true; 20];
    const RUNNING: [bool; 20] = {
        let mut p = [false; 20];
        let mut i = 0;
        while i < 20 {
            p[i] = true;
            i += 2;
        }
        p
    };
    const FINISHED: [bool; 20] = {
        let mut p = [false; 20];
        let mut i = 0;
        while i < 10 {
            p[i] = true;
            i += 1;
        }
        p
    };
    const FAULTED: [bool; 20] = {
        let mut p = [false; 20];
        p[0] = true;
        p[2] = true;
        p
    };
    match state {
        ScanState::Idle => &IDLE,
        ScanState::Armed => &ON,
        ScanState::Running => &RUNNING,
        ScanState::Done | ScanState::Aborted => &FINISHED,
        ScanState::Faulted => &FAULTED,
    }
}

/// Blinks the LED by the published sequencer state, forever.
#[embassy_executor::task]
pub async fn run(mut led: Output<'static>) {
    loop {
        for on in pattern(scan_state()) {
            led.set_level((*on).into());
            Timer::after_millis(50).await;
        }
    }
}
