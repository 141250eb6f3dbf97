//! The simulated sync board for the host: hil-sim's board (the firmware's
//! own core on a virtual clock) on a pseudo-terminal, for `slscan board
//! --sim`, and the in-process tests of the board client against it.

use std::path::Path;

use hil_sim::board::{spawn_on_pty, SimBoardConfig, SimBoardHandle};
use hil_sim::pty::PtyError;

/// A simulated board served on a pseudo-terminal; dropping it stops the board.
pub struct PtyBoard {
    handle: SimBoardHandle,
}

impl PtyBoard {
    /// Starts a simulated board (device jitter seeded with `seed`) on a new pty.
    pub fn start(seed: u64) -> Result<Self, PtyError> {
        let handle = spawn_on_pty(SimBoardConfig {
            seed,
            ..Default::default()
        })?;
        Ok(PtyBoard { handle })
    }

    /// The pty path a serial client opens (`None` if the OS gave no name).
    pub fn path(&self) -> Option<&Path> {
        self.handle.path()
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use hil_sim::board::{spawn_on_channels, SimBoardConfig};
    use protocol::plan::examples;
    use protocol::ScanState;

    use crate::board::client::ClientConfig;
    use crate::board::transport::ChannelTransport;
    use crate::board::{BoardClient, BoardError};

    #[test]
    fn a_pty_board_has_a_path_a_client_can_open() {
        let board = super::PtyBoard::start(1).unwrap();
        let path = board.path().expect("pty path");
        assert!(path.exists(), "{}", path.display());
    }

    /// Client and simulated board in one process over channels (no pty).
    fn in_process() -> (
        BoardClient<ChannelTransport>,
        hil_sim::board::SimBoardHandle,
    ) {
        let (host, board_end) = ChannelTransport::pair();
        let (tx, rx) = board_end.into_parts();
        let board = spawn_on_channels(SimBoardConfig::default(), tx, rx).unwrap();
        let config = ClientConfig {
            attempt_timeout: Duration::from_secs(2),
            attempts: 3,
        };
        let (client, _) = BoardClient::connect(host, config).unwrap();
        (client, board)
    }

    #[test]
    fn runs_a_plan_end_to_end_over_channels() {
        let (mut client, board) = in_process();
        let plan = examples::flood_preliminaries(1);
        let mut seen = 0;
        let outcome = client.run_plan(&plan, 1_000_000, |_| seen += 1).unwrap();
        assert!(outcome.is_clean(), "{outcome:?}");
        assert_eq!(seen, outcome.events.len());
        // 7 floods x (camera + projector pulse) x 2 edges, each mirrored back once.
        assert_eq!(outcome.report.expected, 7 * 2 * 2);
        assert_eq!(board.board().hardware().recorded().len(), 7 * 2 * 2);
    }

    #[test]
    fn a_second_plan_runs_after_the_first() {
        let (mut client, _board) = in_process();
        let first = client
            .run_plan(&examples::head_only(0, 1), 1_000_000, |_| {})
            .unwrap();
        let second = client
            .run_plan(&examples::multiplexed_24_at_5khz(1), 1_000_000, |_| {})
            .unwrap();
        assert!(first.is_clean() && second.is_clean());
        assert!(second.start_tick > first.start_tick);
    }

    #[test]
    fn invalid_plan_is_refused_by_the_board_with_its_reason() {
        let (mut client, _board) = in_process();
        let mut plan = examples::multiplexed_24_at_5khz(1);
        // Patterns 10 us apart: far above any DMD's rate.
        for (k, slot) in plan.slots.iter_mut().enumerate() {
            slot.offset_ns = 2_000 + k as u32 * 10_000;
        }
        let err = client.upload_plan(&plan).unwrap_err();
        assert!(
            matches!(
                err,
                BoardError::Refused {
                    request: "CommitPlan",
                    error: protocol::WireError::Plan(_),
                    ..
                }
            ),
            "{err:?}"
        );
    }

    #[test]
    fn abort_stops_a_running_scan() {
        let (mut client, board) = in_process();
        // A million cycles (80 min of board time): the simulation, however
        // fast, is still running when the abort arrives.
        let plan = examples::multiplexed_24_at_5khz(1_000_000);
        client.upload_plan(&plan).unwrap();
        client.arm().unwrap();
        client.start(1_000_000).unwrap();
        let report = client.abort().unwrap();
        assert_eq!(report.cycles, 1_000_000);
        assert_eq!(client.status().unwrap().state, ScanState::Aborted);
        let played = board.board().hardware().recorded().len();
        assert!(played < 50 * 1_000_000, "{played} edges: stopped early");
    }
}
