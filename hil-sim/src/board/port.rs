//! Where the simulated board's bytes go: a pseudo-terminal (what serial
//! clients open) or in-process channels (unit tests, no pty needed).

use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender};
use std::time::Duration;

use crate::pty::{Pty, PtyError};

/// The board side of a byte link.
pub trait BoardPort {
    /// Waits up to `timeout` for bytes from the host; `Ok(0)` if none came.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, PortError>;

    /// Writes what the link takes now; `Ok(0)` when it is full.
    fn write(&mut self, bytes: &[u8]) -> Result<usize, PortError>;
}

/// The board's port failed.
#[derive(Debug, thiserror::Error)]
pub enum PortError {
    /// The pseudo-terminal failed.
    #[error(transparent)]
    Pty(#[from] PtyError),
    /// The host's end of the channels was dropped.
    #[error("the host end of the channel link was dropped")]
    Disconnected,
}

impl BoardPort for Pty {
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, PortError> {
        Ok(Pty::read(self, buf, timeout)?)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<usize, PortError> {
        Ok(Pty::write(self, bytes)?)
    }
}

/// The board end of an in-process link: chunks of bytes over std channels,
/// the peer of `slscan::board::ChannelTransport`.
#[derive(Debug)]
pub struct ChannelPort {
    tx: Sender<Vec<u8>>,
    rx: Receiver<Vec<u8>>,
    pending: Vec<u8>,
}

impl ChannelPort {
    /// A port sending to the host on `tx` and hearing it on `rx`.
    pub fn new(tx: Sender<Vec<u8>>, rx: Receiver<Vec<u8>>) -> Self {
        Self {
            tx,
            rx,
            pending: Vec::new(),
        }
    }
}

impl BoardPort for ChannelPort {
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> Result<usize, PortError> {
        if self.pending.is_empty() {
            match self.rx.recv_timeout(timeout) {
                Ok(chunk) => self.pending = chunk,
                Err(RecvTimeoutError::Timeout) => return Ok(0),
                Err(RecvTimeoutError::Disconnected) => return Err(PortError::Disconnected),
            }
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        Ok(n)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<usize, PortError> {
        self.tx
            .send(bytes.to_vec())
            .map_err(|_| PortError::Disconnected)?;
        Ok(bytes.len())
    }
}
