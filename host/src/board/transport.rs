//! Byte transports under the board client: a serial port (the real board on
//! `/dev/ttyACM0`, or hil-sim's pty), or in-process channels for tests that run
//! the client and a board core in one process.

use std::io::{Read, Write};
use std::path::Path;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::Duration;

use super::error::LinkError;

/// Moves raw bytes to and from a board. Framing is the client's job.
pub trait Transport {
    /// Sends all of `bytes`.
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError>;

    /// Waits up to `timeout` for bytes and copies what arrived into `buf`;
    /// `Ok(0)` means nothing came in time.
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError>;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        (**self).send(bytes)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        (**self).recv(buf, timeout)
    }
}

/// Baud rate asked of the port. USB CDC-ACM and ptys ignore it; a UART
/// bridge would not.
pub const DEFAULT_BAUD: u32 = 115_200;

/// A serial port opened by path.
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("port", &self.port.name())
            .finish()
    }
}

impl SerialTransport {
    /// Opens `path` (8N1, no flow control, exclusive) at `baud`.
    pub fn open(path: &Path, baud: u32) -> Result<Self, LinkError> {
        let mut port = serialport::new(path.to_string_lossy(), baud)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(|source| LinkError::Open {
                path: path.to_path_buf(),
                source,
            })?;
        // Stale bytes from an earlier session would only look like garbage.
        let _ = port.clear(serialport::ClearBuffer::Input);
        // USB CDC-ACM firmware (embassy's `wait_connection`) takes DTR as
        // "host connected". Linux raises it on open; asking again is cheap.
        // A pty has no modem lines, so this is best-effort.
        let _ = port.write_data_terminal_ready(true);
        Ok(Self { port })
    }
}

impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        let gone = |source| LinkError::PortGone {
            operation: "write",
            source,
        };
        self.port.write_all(bytes).map_err(gone)?;
        self.port.flush().map_err(gone)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        let gone = |source| LinkError::PortGone {
            operation: "read",
            source,
        };
        // serialport's read waits (poll) for at most the port timeout.
        self.port
            .set_timeout(timeout.max(Duration::from_millis(1)))
            .map_err(|e| gone(e.into()))?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(0),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => Ok(0),
            Err(e) => Err(gone(e)),
        }
    }
}

/// One end of an in-process byte link: chunks of bytes over std channels (the
/// habit of postcard-rpc's `test_channels`). Dropping one end makes the other
/// fail with [`LinkError::PortGone`], like an unplugged cable.
#[derive(Debug)]
pub struct ChannelTransport {
    tx: Sender<Vec<u8>>,
    rx: Receiver<Vec<u8>>,
    pending: Vec<u8>,
}

impl ChannelTransport {
    /// A transport sending on `tx` and receiving from `rx`.
    pub fn new(tx: Sender<Vec<u8>>, rx: Receiver<Vec<u8>>) -> Self {
        Self {
            tx,
            rx,
            pending: Vec::new(),
        }
    }

    /// Two connected ends.
    pub fn pair() -> (Self, Self) {
        let (a_tx, b_rx) = mpsc::channel();
        let (b_tx, a_rx) = mpsc::channel();
        (Self::new(a_tx, a_rx), Self::new(b_tx, b_rx))
    }

    /// Takes the ends apart, for a peer that speaks raw channels.
    pub fn into_parts(self) -> (Sender<Vec<u8>>, Receiver<Vec<u8>>) {
        (self.tx, self.rx)
    }
}

fn disconnected(operation: &'static str) -> LinkError {
    LinkError::PortGone {
        operation,
        source: std::io::Error::new(std::io::ErrorKind::BrokenPipe, "channel peer dropped"),
    }
}

impl Transport for ChannelTransport {
    fn send(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.tx
            .send(bytes.to_vec())
            .map_err(|_| disconnected("write"))
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, LinkError> {
        if self.pending.is_empty() {
            match self.rx.recv_timeout(timeout) {
                Ok(chunk) => self.pending = chunk,
                Err(RecvTimeoutError::Timeout) => return Ok(0),
                Err(RecvTimeoutError::Disconnected) => return Err(disconnected("read")),
            }
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_pair_carries_bytes_in_small_reads() {
        let (mut a, mut b) = ChannelTransport::pair();
        a.send(&[1, 2, 3, 4, 5]).unwrap();
        let mut buf = [0u8; 2];
        let mut got = Vec::new();
        while got.len() < 5 {
            let n = b.recv(&mut buf, Duration::from_secs(5)).unwrap();
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, vec![1, 2, 3, 4, 5]);
    }

    #[test]
    fn channel_recv_times_out_with_zero() {
        let (_a, mut b) = ChannelTransport::pair();
        let mut buf = [0u8; 8];
        assert_eq!(b.recv(&mut buf, Duration::from_millis(1)).unwrap(), 0);
    }

    #[test]
    fn dropped_peer_is_a_port_gone_error() {
        let (a, mut b) = ChannelTransport::pair();
        drop(a);
        let mut buf = [0u8; 8];
        let err = b.recv(&mut buf, Duration::from_millis(1)).unwrap_err();
        assert!(
            matches!(
                err,
                LinkError::PortGone {
                    operation: "read",
                    ..
                }
            ),
            "{err:?}"
        );
        assert!(matches!(
            b.send(&[0]),
            Err(LinkError::PortGone {
                operation: "write",
                ..
            })
        ));
    }

    #[test]
    fn opening_a_missing_port_names_it() {
        let err = SerialTransport::open(Path::new("/dev/does-not-exist-slscan"), DEFAULT_BAUD)
            .unwrap_err();
        let text = err.to_string();
        assert!(text.contains("/dev/does-not-exist-slscan"), "{text}");
    }
}
