//! The host link: USB CDC-ACM bytes <-> board-core's `Link`, and the scan
//! poll. One task owns the link, the trigger hardware and the USB class, so
//! requests, feedback checks and events never race.
//!
//! ```text
//! USB OUT packet --Link::receive--> Dispatcher (board-core) --> response frames --+
//! cycle IRQ / 1 ms tick --Link::poll--> Sequencer::poll --> event frames ---------+--> TxQueue --> USB IN
//! ```
//!
//! Host gone (unplug, bus reset, suspend, endpoint disabled) mid-scan:
//! `Link::host_link_lost` aborts the scan with every output inactive; the
//! host's serial port errors at once, and after reconnecting `GetStatus`
//! shows `Aborted` with the scan report.

use core::sync::atomic::{AtomicBool, AtomicU8, Ordering};

use board_core::Link;
use embassy_futures::select::{select3, Either3};
use embassy_stm32::peripherals::USB;
use embassy_stm32::usb::Driver;
use embassy_time::{with_timeout, Duration, TimeoutError, Timer};
use embassy_usb::class::cdc_acm::CdcAcmClass;
use embassy_usb::driver::EndpointError;
use heapless::Vec;
use protocol::limits::MAX_FRAME_BYTES;
use protocol::{decode_payload, BoardFrame, Event, FrameAccumulator, Response, ScanState};

use crate::board::active::hardware::G474Hardware;

/// USB full-speed bulk packet size.
pub const USB_PACKET_BYTES: usize = 64;
/// Outgoing bytes buffered between the link and the USB IN endpoint: a
/// response plus a burst of events.
pub const TX_QUEUE_BYTES: usize = 4 * MAX_FRAME_BYTES;
/// Poll period of the sequencer while nothing else wakes the task: how
/// late a feedback check or the end of a scan may be noticed.
const POLL_PERIOD_MS: u64 = 1;
/// How long one IN packet may wait for the host to read it.
const WRITE_TIMEOUT_MS: u64 = 100;
/// Re-check period while the host link is down.
const LINK_DOWN_POLL_MS: u64 = 10;

/// The CDC-ACM class on the G474's USB driver.
pub type Class = CdcAcmClass<'static, Driver<'static, USB>>;

/// The host has configured the device (false after a bus reset).
static USB_CONFIGURED: AtomicBool = AtomicBool::new(false);
/// The bus is suspended (host asleep, or the cable pulled: no more SOFs).
static USB_SUSPENDED: AtomicBool = AtomicBool::new(false);
/// The sequencer state as a small number, for the status LED.
static SCAN_STATE: AtomicU8 = AtomicU8::new(0);

/// The last published sequencer state (status LED).
pub fn scan_state() -> ScanState {
    match SCAN_STATE.load(Ordering::Relaxed) {
        1 => ScanState::Armed,
        2 => ScanState::Running,
        3 => ScanState::Done,
        4 => ScanState::Aborted,
        5 => ScanState::Faulted,
        _ => ScanState::Idle,
    }
}

fn publish(state: ScanState) {
    let code = match state {
        ScanState::Idle => 0,
        ScanState::Armed => 1,
        ScanState::Running => 2,
        ScanState::Done => 3,
        ScanState::Aborted => 4,
        ScanState::Faulted => 5,
    };
    if SCAN_STATE.swap(code, Ordering::Relaxed) != code {
        defmt::info!("sequencer state: {}", defmt::Debug2Format(&state));
    }
}

/// Tracks the USB device state for the link task (embassy-usb calls it
/// from the device task).
pub struct UsbStateHandler;

impl embassy_usb::Handler for UsbStateHandler {
    fn reset(&mut self) {
        USB_CONFIGURED.store(false, Ordering::Relaxed);
        defmt::warn!("usb: bus reset");
    }
    fn configured(&mut self, configured: bool) {
        USB_CONFIGURED.store(configured, Ordering::Relaxed);
        defmt::info!("usb: configured = {}", configured);
    }
    fn suspended(&mut self, suspended: bool) {
        USB_SUSPENDED.store(suspended, Ordering::Relaxed);
        if suspended {
            defmt::warn!("usb: suspended (host gone or asleep)");
        } else {
            defmt::info!("usb: resumed");
        }
    }
}

/// Whether the host can talk to us: configured and not suspended.
fn usb_link_up() -> bool {
    USB_CONFIGURED.load(Ordering::Relaxed) && !USB_SUSPENDED.load(Ordering::Relaxed)
}

/// Logs every error and scan outcome the link sends to the host, by
/// decoding the outgoing frames again (board-core encodes them; the log is
/// the firmware's view of what the host was told).
struct TxLog {
    frames: FrameAccumulator,
}

impl TxLog {
    const fn new() -> Self {
        TxLog {
            frames: FrameAccumulator::new(),
        }
    }

    fn log(&mut self, frame: &[u8]) {
        self.frames.feed(frame, |payload| {
            let Ok(decoded) = payload.and_then(decode_payload::<BoardFrame>) else {
                return;
            };
            match decoded {
                BoardFrame::Response {
                    response: Response::Refused(error),
                    ..
                } => defmt::warn!("refused: {}", defmt::Debug2Format(&error)),
                BoardFrame::LinkError(error) => {
                    defmt::warn!(
                        "unreadable frame from host: {}",
                        defmt::Debug2Format(&error)
                    )
                }
                BoardFrame::Event(event @ Event::ScanFinished { .. }) => {
                    defmt::info!("{}", defmt::Debug2Format(&event))
                }
                BoardFrame::Event(event @ Event::HardwareFault { .. }) => {
                    defmt::error!("{}", defmt::Debug2Format(&event))
                }
                BoardFrame::Event(event) => defmt::debug!("{}", defmt::Debug2Format(&event)),
                BoardFrame::Response { .. } => {}
            }
        });
    }
}

/// Frames waiting for the USB IN endpoint. Never blocks the link: a frame
/// that does not fit is dropped and counted (the host sees the gap as a
/// missing response and times out; board-core counts dropped events).
pub struct TxQueue {
    bytes: Vec<u8, TX_QUEUE_BYTES>,
    dropped_frames: u32,
    log: TxLog,
}

impl TxQueue {
    const fn new() -> Self {
        TxQueue {
            bytes: Vec::new(),
            dropped_frames: 0,
            log: TxLog::new(),
        }
    }

    fn push(&mut self, frame: &[u8]) {
        self.log.log(frame);
        if self.bytes.extend_from_slice(frame).is_err() {
            self.dropped_frames = self.dropped_frames.saturating_add(1);
            defmt::warn!(
                "usb: tx queue full, frame of {=usize} bytes dropped ({=u32} so far)",
                frame.len(),
                self.dropped_frames
            );
        }
    }

    /// Writes everything queued, in full-size packets, then a zero-length
    /// packet if the last one was full (ends the host's bulk transfer). A
    /// host that has the port open but stops reading for
    /// [`WRITE_TIMEOUT_MS`] loses the queued frames rather than stalling
    /// the link (and with it the scan's feedback checks).
    async fn flush(&mut self, class: &mut Class) -> Result<(), EndpointError> {
        if self.bytes.is_empty() {
            return Ok(());
        }
        let mut last_full = false;
        for packet in self.bytes.chunks(USB_PACKET_BYTES) {
            let sent = with_timeout(
                Duration::from_millis(WRITE_TIMEOUT_MS),
                class.write_packet(packet),
            )
            .await;
            match sent {
                Ok(result) => result?,
                Err(TimeoutError) => {
                    defmt::warn!(
                        "usb: host not reading, {=usize} queued bytes dropped",
                        self.bytes.len()
                    );
                    self.dropped_frames = self.dropped_frames.saturating_add(1);
                    self.bytes.clear();
                    return Ok(());
                }
            }
            last_full = packet.len() == USB_PACKET_BYTES;
        }
        if last_full {
            class.write_packet(&[]).await?;
        }
        self.bytes.clear();
        Ok(())
    }
}

/// The link task: serves the host while connected; on disconnect stops a
/// running scan through `HostLinkLost` and waits for the next connection.
#[embassy_executor::task]
pub async fn run(mut class: Class, mut hw: G474Hardware, link: &'static mut Link) {
    let mut tx = TxQueue::new();
    let mut rx = [0u8; USB_PACKET_BYTES];
    loop {
        // Suspended-but-configured keeps the endpoints enabled, so
        // `wait_connection` alone could return at once: wait for the link.
        while !usb_link_up() {
            Timer::after_millis(LINK_DOWN_POLL_MS).await;
        }
        class.wait_connection().await;
        defmt::info!("usb: host link up");
        let result = serve(&mut class, &mut hw, link, &mut tx, &mut rx).await;
        defmt::warn!("usb: host link down ({})", result.err());
        tx.bytes.clear();
        host_gone(&mut hw, link);
    }
}

/// Serves one connection until the endpoint reports the host gone.
async fn serve(
    class: &mut Class,
    hw: &mut G474Hardware,
    link: &mut Link,
    tx: &mut TxQueue,
    rx: &mut [u8; USB_PACKET_BYTES],
) -> Result<(), EndpointError> {
    loop {
        let woke = select3(
            class.read_packet(rx),
            hw.wait_cycle(),
            Timer::after_millis(POLL_PERIOD_MS),
        )
        .await;
        if let Either3::First(read) = woke {
            let n = read?;
            link.receive(&rx[..n], hw, &mut |frame: &[u8]| tx.push(frame));
        }
        link.poll(hw, &mut |frame: &[u8]| tx.push(frame));
        publish(link.dispatcher().sequencer().state());
        tx.flush(class).await?;
        if !usb_link_up() {
            return Err(EndpointError::Disabled);
        }
    }
}

/// The host went away: board-core stops any scan (outputs inactive,
/// armed/running -> aborted), drops the half-received frame and the plan
/// upload. The state stays for `GetStatus` after reconnecting.
fn host_gone(hw: &mut G474Hardware, link: &mut Link) {
    let was = link.dispatcher().sequencer().state();
    link.host_link_lost(hw);
    if matches!(was, ScanState::Armed | ScanState::Running) {
        defmt::warn!("usb: host gone mid-scan, scan aborted, outputs inactive");
    }
    publish(link.dispatcher().sequencer().state());
}
