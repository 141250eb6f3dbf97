//! A scripted board for the client's unit tests: a thread on the far end of
//! a [`ChannelTransport`] that answers each request as a test script says,
//! including with garbage, silence or the wrong answer.

use std::thread::JoinHandle;
use std::time::Duration;

use protocol::limits::MAX_FRAME_BYTES;
use protocol::{
    decode_payload, encode_frame, BoardFrame, BoardLimits, DeviceInfo, FirmwareVersion,
    FrameAccumulator, HostFrame, RequestId, ResetCause, Response, PROTOCOL_VERSION,
};

use super::client::{BoardClient, ClientConfig};
use super::transport::{ChannelTransport, Transport};

/// Timeouts of scripted tests: short, the board is in-process.
pub const SHORT: ClientConfig = ClientConfig {
    attempt_timeout: Duration::from_millis(100),
    attempts: 3,
};

/// The device info the scripted board claims.
pub fn info() -> DeviceInfo {
    DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 7,
        limits: BoardLimits::STM32G474,
        reset_cause: ResetCause::Simulated,
    }
}

/// One encoded board frame.
pub fn frame(message: &BoardFrame) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_BYTES];
    let n = encode_frame(message, &mut buf).expect("board frames fit");
    buf[..n].to_vec()
}

/// The encoded answer `response` to request `id`.
pub fn answer(id: RequestId, response: Response) -> Vec<u8> {
    frame(&BoardFrame::Response { id, response })
}

/// A scripted board on a thread: `script` sees each request (with how many
/// came before) and returns the raw bytes to send back. The thread returns
/// the requests it saw when the client hangs up.
pub fn scripted_board(
    mut script: impl FnMut(usize, &HostFrame) -> Vec<Vec<u8>> + Send + 'static,
) -> (BoardClient<ChannelTransport>, JoinHandle<Vec<HostFrame>>) {
    let (host, mut board) = ChannelTransport::pair();
    let handle = std::thread::spawn(move || {
        let mut rx = FrameAccumulator::new();
        let mut seen = Vec::new();
        let mut buf = [0u8; 256];
        loop {
            let n = match board.recv(&mut buf, Duration::from_millis(10)) {
                Ok(n) => n,
                Err(_) => return seen,
            };
            let mut frames = Vec::new();
            rx.feed(&buf[..n], |f| {
                frames.push(f.and_then(decode_payload::<HostFrame>))
            });
            for f in frames.into_iter().flatten() {
                for bytes in script(seen.len(), &f) {
                    let _ = board.send(&bytes);
                }
                seen.push(f);
            }
        }
    });
    (BoardClient::new(host, SHORT), handle)
}

/// Hangs up and returns the requests the board saw.
pub fn finish(
    client: BoardClient<ChannelTransport>,
    board: JoinHandle<Vec<HostFrame>>,
) -> Vec<HostFrame> {
    drop(client);
    board.join().expect("scripted board thread")
}
