//! Whole board jobs built from the client's requests: upload a plan in
//! chunks, run it, follow it to its end.
//!
//! While a scan runs, a real board is silent unless feedback deviates, so
//! silence alone proves nothing: after each quiet spell the client asks for
//! the board's status. A board that stopped answering then fails that request
//! with a timeout, within `attempts x attempt_timeout` of host time, however
//! long the scan is.

use std::time::{Duration, Instant};

use protocol::{Event, PlanError, PlanSummary, ScanPlan, ScanReport, ScanState};

use super::client::BoardClient;
use super::error::BoardError;
use super::transport::Transport;

/// What a scan did, as the board reported it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScanOutcome {
    /// The compiled plan.
    pub summary: PlanSummary,
    /// Board tick at which the first cycle started.
    pub start_tick: u64,
    /// How the scan ended (`Done`, `Aborted` or `Faulted`).
    pub state: ScanState,
    /// The board's final counters.
    pub report: ScanReport,
    /// Every event the board sent during the scan, in order.
    pub events: Vec<Event>,
}

impl ScanOutcome {
    /// True when the scan ran to its end with every feedback edge on time
    /// and every pattern's light checked inside its exposure.
    pub fn is_clean(&self) -> bool {
        let r = &self.report;
        self.state == ScanState::Done
            && r.expected == r.on_time
            && r.unexpected == 0
            && r.events_dropped == 0
            && r.out_of_window == 0
            && r.patterns_unchecked == 0
    }
}

/// Ticks the board may run past a scan's planned end before the client calls
/// it stuck: the feedback check waits out the last late window, far less.
const OVERRUN_SLACK_TICKS: u64 = 170_000_000;

impl<T: Transport> BoardClient<T> {
    /// Uploads `plan` (header, then one request per exposure) and has the
    /// board validate and compile it. A plan with more heads than the board
    /// reported lines for (after `hello` or `info`) is refused before
    /// anything is sent ([`BoardError::PlanExceedsBoard`]); the rest of
    /// validation is the board's.
    pub fn upload_plan(&mut self, plan: &ScanPlan) -> Result<PlanSummary, BoardError> {
        if let Some(limits) = self.board_limits() {
            if plan.heads.len() > limits.max_heads() {
                return Err(BoardError::PlanExceedsBoard(
                    PlanError::TooManyHeadsForBoard {
                        heads: plan.heads.len() as u8,
                        output_channels: limits.output_channels,
                        feedback_channels: limits.feedback_channels,
                        max_heads: limits.max_heads() as u8,
                    },
                ));
            }
        }
        self.begin_plan(&plan.header())?;
        for index in 0..plan.exposures.len() {
            if let Some(exposure) = plan.wire_exposure(index) {
                self.add_exposure(index as u16, &exposure)?;
            }
        }
        self.commit_plan()
    }

    /// Uploads, arms and starts `plan` `start_delay_ns` after the board gets
    /// the request, then follows it to its end, handing each event to
    /// `on_event` as it comes.
    pub fn run_plan(
        &mut self,
        plan: &ScanPlan,
        start_delay_ns: u32,
        mut on_event: impl FnMut(&Event),
    ) -> Result<ScanOutcome, BoardError> {
        let summary = self.upload_plan(plan)?;
        self.arm()?;
        let start_tick = self.start(start_delay_ns)?;
        let end_tick = start_tick + summary.period_ticks as u64 * summary.repeat_count as u64;
        let mut events = Vec::new();
        let (state, report) = self.follow_scan(end_tick, |event| {
            on_event(event);
            events.push(*event);
        })?;
        Ok(ScanOutcome {
            summary,
            start_tick,
            state,
            report,
            events,
        })
    }

    /// Follows a running scan planned to end at board tick `end_tick` until
    /// it finishes; returns its final state and counters.
    pub fn follow_scan(
        &mut self,
        end_tick: u64,
        mut on_event: impl FnMut(&Event),
    ) -> Result<(ScanState, ScanReport), BoardError> {
        let quiet = self.config().attempt_timeout;
        // Host time is used only to space the status checks: one after each
        // quiet spell, and at least one per spell while events stream, so a
        // board stuck sending events cannot keep the client waiting forever.
        let mut last_check = Instant::now();
        loop {
            let event = self.next_event(quiet)?;
            if let Some(event) = event {
                on_event(&event);
                if let Event::ScanFinished { state, report } = event {
                    return Ok((state, report));
                }
                if last_check.elapsed() < quiet {
                    continue;
                }
            }
            last_check = Instant::now();
            let status = self.status()?;
            match status.state {
                // Finished, but its event was lost: the counters are the
                // board's either way.
                ScanState::Done | ScanState::Aborted | ScanState::Faulted => {
                    return self.drain_finish(status.state, status.report, &mut on_event)
                }
                _ if status.now_tick > end_tick + OVERRUN_SLACK_TICKS => {
                    return Err(BoardError::ScanOverran {
                        state: status.state,
                        now_tick: status.now_tick,
                        end_tick,
                    })
                }
                _ => {}
            }
        }
    }

    /// After a status showed the scan over: take the events already queued
    /// (the `ScanFinished` among them wins over the status counters). The
    /// board sends in order, so an event sent before the status answer was
    /// read, and queued, while the client waited for that answer.
    fn drain_finish(
        &mut self,
        state: ScanState,
        report: ScanReport,
        on_event: &mut impl FnMut(&Event),
    ) -> Result<(ScanState, ScanReport), BoardError> {
        while let Some(event) = self.next_event(Duration::ZERO)? {
            on_event(&event);
            if let Event::ScanFinished { state, report } = event {
                return Ok((state, report));
            }
        }
        Ok((state, report))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::transport::ChannelTransport;
    use protocol::plan::examples;

    /// A board that runs plans but whose `ScanFinished` event never arrives;
    /// its status says `status_state` at `status_tick`.
    fn board_losing_the_end(
        status_state: ScanState,
        status_tick: u64,
    ) -> BoardClient<ChannelTransport> {
        use crate::board::test_board::{answer, scripted_board};
        use protocol::{BoardStatus, PlanSummary, Request, Response};
        let report = ScanReport {
            cycles: 1,
            expected: 4,
            on_time: 4,
            ..ScanReport::default()
        };
        let (client, _board) = scripted_board(move |_, f| {
            let response = match &f.request {
                Request::BeginPlan(_) => Response::PlanBegun,
                Request::AddExposure { index, .. } => Response::ExposureAdded { index: *index },
                Request::CommitPlan => Response::PlanCommitted(PlanSummary {
                    edges_per_cycle: 4,
                    period_ticks: 1_000,
                    repeat_count: 1,
                }),
                Request::Arm => Response::Armed,
                Request::Start { .. } => Response::Started { start_tick: 500 },
                _ => Response::Status(BoardStatus {
                    state: status_state,
                    now_tick: status_tick,
                    plan_loaded: true,
                    report,
                }),
            };
            vec![answer(f.id, response)]
        });
        client
    }

    /// A plan's heads are checked against the limits the board reported
    /// before any of the plan goes out; a plan within them is sent whole.
    #[test]
    fn plan_with_more_heads_than_the_board_has_lines_is_not_sent() {
        use crate::board::test_board::{answer, info, scripted_board};
        use protocol::{Request, Response};
        let (mut client, board) = scripted_board(|_, f| {
            let response = match &f.request {
                Request::Hello { .. } => Response::Hello(info()),
                Request::BeginPlan(_) => Response::PlanBegun,
                Request::AddExposure { index, .. } => Response::ExposureAdded { index: *index },
                _ => Response::PlanCommitted(PlanSummary {
                    edges_per_cycle: 4,
                    period_ticks: 1_000,
                    repeat_count: 1,
                }),
            };
            vec![answer(f.id, response)]
        });
        // Before the handshake the client knows no limits.
        assert_eq!(client.board_limits(), None);
        client.hello().unwrap();
        let err = client
            .upload_plan(&examples::all_heads_psp(3, 1))
            .unwrap_err();
        assert!(
            matches!(
                err,
                BoardError::PlanExceedsBoard(PlanError::TooManyHeadsForBoard {
                    heads: 3,
                    output_channels: 4,
                    feedback_channels: 4,
                    max_heads: 2
                })
            ),
            "{err:?}"
        );
        assert_eq!(
            err.to_string(),
            "plan not sent: the plan drives 3 heads; this board has 4 trigger lines and 4 \
             feedback lines (two of each per head), 2 heads"
        );
        client.upload_plan(&examples::all_heads_psp(2, 1)).unwrap();
        drop(client);
        let seen = board.join().unwrap();
        // Hello, then the two-head plan only: header, 16 exposures, commit.
        assert!(matches!(seen[0].request, Request::Hello { .. }));
        assert!(matches!(&seen[1].request, Request::BeginPlan(h) if h.heads.len() == 2));
        assert_eq!(seen.len(), 1 + 1 + 16 + 1);
    }

    #[test]
    fn lost_finish_event_is_made_up_for_by_the_status() {
        let mut client = board_losing_the_end(ScanState::Done, 2_000);
        let outcome = client
            .run_plan(&examples::head_only(0, 1), 1_000_000, |_| {})
            .unwrap();
        assert_eq!(outcome.state, ScanState::Done);
        assert_eq!(outcome.report.on_time, 4);
    }

    #[test]
    fn board_running_long_past_the_plan_end_is_an_overrun() {
        let mut client =
            board_losing_the_end(ScanState::Running, 500 + 1_000 + 10 * OVERRUN_SLACK_TICKS);
        let err = client
            .run_plan(&examples::head_only(0, 1), 1_000_000, |_| {})
            .unwrap_err();
        assert!(
            matches!(
                err,
                BoardError::ScanOverran {
                    end_tick: 1_500,
                    ..
                }
            ),
            "{err:?}"
        );
    }
}
