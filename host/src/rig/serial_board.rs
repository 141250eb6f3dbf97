//! The sync board behind [`Board`]: the host's serial [`BoardClient`] on a
//! serial port — the STM32 board's USB CDC-ACM port (`/dev/ttyACM0`) on
//! hardware, or hil-sim's pseudo-terminal in the simulator. Both rigs share
//! it, so the simulated rig exercises the very code a real scan runs.

use std::path::Path;

use protocol::ScanPlan;

use super::{require_clean, Board, RigError};
use crate::board::{BoardClient, BoardError, ClientConfig, ScanOutcome, SerialTransport};

/// Delay from `Start` to the first cycle, board nanoseconds: room for the
/// `Start` answer to reach the host before the first edge.
pub const START_DELAY_NS: u32 = 1_000_000;

/// Baud rate asked of the port (ignored by USB CDC-ACM and ptys, which run
/// at bus speed; kept for a real UART).
pub const BAUD: u32 = 115_200;

/// A connected sync board.
pub struct SerialBoard {
    client: BoardClient<SerialTransport>,
}

impl SerialBoard {
    /// Opens `port` and shakes hands with the board on it; fails with a
    /// [`BoardError`] naming the port when it is missing or silent.
    pub fn open(port: &Path, client: ClientConfig) -> Result<Self, RigError> {
        let transport = SerialTransport::open(port, BAUD).map_err(BoardError::from)?;
        let (client, info) = BoardClient::connect(transport, client)?;
        tracing::info!(
            board_id = format_args!("{:#x}", info.board_id),
            port = %port.display(),
            "sync board connected"
        );
        Ok(SerialBoard { client })
    }
}

impl Board for SerialBoard {
    fn run_plan(&mut self, plan: &ScanPlan) -> Result<ScanOutcome, RigError> {
        let outcome = self.client.run_plan(plan, START_DELAY_NS, |event| {
            tracing::debug!(?event, "board event");
        })?;
        require_clean(&outcome)?;
        Ok(outcome)
    }

    fn limits(&self) -> Option<protocol::BoardLimits> {
        self.client.board_limits()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_port_is_a_board_error_naming_it() {
        let port = Path::new("/dev/slscan-no-such-port");
        let err = SerialBoard::open(port, ClientConfig::default())
            .err()
            .expect("no such port");
        assert!(matches!(err, RigError::Board(_)), "{err:?}");
        let text = format!("{:#}", anyhow::Error::from(err));
        assert!(text.contains("slscan-no-such-port"), "{text}");
    }
}
