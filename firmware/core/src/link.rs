//! Frames in -> requests -> responses and events out. No I/O: the caller
//! passes the bytes it received and a sink for the bytes to send, so the
//! STM32's USB task, hil-sim's pty and the fuzz targets drive the very same
//! code.
//!
//! ```text
//! bytes --FrameAccumulator--> HostFrame --Dispatcher::handle--> Response
//!   |   bad frame -> BoardFrame::LinkError                         |
//!   +------------------------------------------------> tx(frame) <-+
//! poll(): Sequencer::poll (captures, end of scan) -> BoardFrame::Event -> tx
//! ```

use protocol::limits::{ns_to_ticks, MAX_FRAME_BYTES};
use protocol::{
    decode_payload, encode_frame, BoardFrame, BoardStatus, DeviceInfo, FrameAccumulator, HostFrame,
    PlanSummary, Request, RequestId, Response, ScanPlan, WireError, PROTOCOL_VERSION,
};

use crate::hardware::TriggerHardware;
use crate::sequencer::Sequencer;

/// A plan being uploaded exposure by exposure.
#[derive(Debug)]
struct Upload {
    plan: ScanPlan,
    announced: u16,
}

/// Request handling: plan upload, validation, the sequencer.
#[derive(Debug)]
pub struct Dispatcher {
    info: DeviceInfo,
    upload: Option<Upload>,
    sequencer: Sequencer,
    last_answer: Option<(RequestId, Response)>,
}

impl Dispatcher {
    /// A dispatcher for a board described by `info`.
    pub fn new(info: DeviceInfo) -> Self {
        Dispatcher {
            info,
            upload: None,
            sequencer: Sequencer::new(),
            last_answer: None,
        }
    }

    /// The board's device info.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    /// The sequencer (state, table, report).
    pub fn sequencer(&self) -> &Sequencer {
        &self.sequencer
    }

    /// The sequencer, mutably (to poll it or pop events).
    pub fn sequencer_mut(&mut self) -> &mut Sequencer {
        &mut self.sequencer
    }

    /// Answers the request of frame `id`. A repeat of the last id is a
    /// retry whose answer was lost: it gets the same answer again without
    /// running twice (a retried `AddExposure` or `Start` would otherwise be
    /// refused). `Hello` always runs and forgets the last answer, so a new
    /// host session may reuse ids.
    pub fn handle_frame<H: TriggerHardware>(
        &mut self,
        id: RequestId,
        request: &Request,
        hw: &mut H,
    ) -> Response {
        if let Some((last_id, answer)) = &self.last_answer {
            if *last_id == id && !matches!(request, Request::Hello { .. }) {
                return answer.clone();
            }
        }
        let answer = self.handle(request, hw);
        self.last_answer = Some((id, answer.clone()));
        answer
    }

    /// Answers one request (no retry detection; see [`Dispatcher::handle_frame`]).
    pub fn handle<H: TriggerHardware>(&mut self, request: &Request, hw: &mut H) -> Response {
        match self.try_handle(request, hw) {
            Ok(response) => response,
            Err(error) => Response::Refused(error),
        }
    }

    fn try_handle<H: TriggerHardware>(
        &mut self,
        request: &Request,
        hw: &mut H,
    ) -> Result<Response, WireError> {
        Ok(match request {
            Request::Hello { protocol_version } => {
                if *protocol_version != PROTOCOL_VERSION {
                    return Err(WireError::UnsupportedVersion {
                        board: PROTOCOL_VERSION,
                        host: *protocol_version,
                    });
                }
                Response::Hello(self.info)
            }
            Request::GetInfo => Response::Info(self.info),
            Request::BeginPlan(header) => {
                self.upload = Some(Upload {
                    plan: ScanPlan::from_header(header),
                    announced: header.exposure_count,
                });
                Response::PlanBegun
            }
            Request::AddExposure { index, exposure } => {
                let upload = self.upload.as_mut().ok_or(WireError::NoPlanBegun)?;
                let expected = upload.plan.exposures.len() as u16;
                if *index != expected {
                    return Err(WireError::ExposureOutOfSequence {
                        expected,
                        received: *index,
                    });
                }
                upload.plan.push_wire_exposure(exposure)?;
                Response::ExposureAdded { index: *index }
            }
            Request::CommitPlan => self.commit()?,
            Request::Arm => {
                self.sequencer.arm(hw)?;
                Response::Armed
            }
            Request::Start { delay_ns } => {
                // A start sooner than the board can arm is moved out, the same on
                // silicon and in simulation.
                let delay = ns_to_ticks(*delay_ns as u64, self.info.limits.timer_clock_hz)
                    .max(self.info.limits.min_start_delay_ticks as u64);
                let start_tick = self.sequencer.start(hw, delay)?;
                Response::Started { start_tick }
            }
            Request::Abort => Response::Aborted(self.sequencer.abort(hw)),
            Request::GetStatus => Response::Status(BoardStatus {
                state: self.sequencer.state(),
                now_tick: hw.now_ticks(),
                plan_loaded: self.sequencer.plan_loaded(),
                report: self.sequencer.report(),
            }),
            Request::Ping { nonce } => Response::Pong { nonce: *nonce },
        })
    }

    fn commit(&mut self) -> Result<Response, WireError> {
        let upload = self.upload.take().ok_or(WireError::NoPlanBegun)?;
        let received = upload.plan.exposures.len() as u16;
        if received != upload.announced {
            return Err(WireError::PlanIncomplete {
                announced: upload.announced,
                received,
            });
        }
        let valid = upload.plan.validate(&self.info.limits)?;
        self.sequencer.load(&valid)?;
        let table = self.sequencer.table();
        Ok(Response::PlanCommitted(PlanSummary {
            edges_per_cycle: table.edges().len() as u16,
            period_ticks: table.period_ticks(),
            repeat_count: table.repeat_count(),
        }))
    }
}

/// The board end of the link: frame accumulator plus dispatcher.
#[derive(Debug)]
pub struct Link {
    rx: FrameAccumulator,
    dispatcher: Dispatcher,
}

impl Link {
    /// A link for a board described by `info`.
    pub fn new(info: DeviceInfo) -> Self {
        Link {
            rx: FrameAccumulator::new(),
            dispatcher: Dispatcher::new(info),
        }
    }

    /// The dispatcher (sequencer state, info).
    pub fn dispatcher(&self) -> &Dispatcher {
        &self.dispatcher
    }

    /// The dispatcher, mutably.
    pub fn dispatcher_mut(&mut self) -> &mut Dispatcher {
        &mut self.dispatcher
    }

    /// Feeds received bytes (any chunking). Each complete frame is answered
    /// through `tx` (one call per encoded frame, `0x00` terminator
    /// included); unreadable frames get a `BoardFrame::LinkError`. Queued
    /// events follow the responses.
    pub fn receive<H: TriggerHardware>(
        &mut self,
        bytes: &[u8],
        hw: &mut H,
        tx: &mut impl FnMut(&[u8]),
    ) {
        let Link { rx, dispatcher } = self;
        rx.feed(bytes, |frame| {
            let answer = match frame.and_then(decode_payload::<HostFrame>) {
                Ok(HostFrame { id, request }) => BoardFrame::Response {
                    id,
                    response: dispatcher.handle_frame(id, &request, hw),
                },
                Err(error) => BoardFrame::LinkError(WireError::Frame(error)),
            };
            send(&answer, tx);
        });
        self.flush_events(tx);
    }

    /// Advances the sequencer (captures, end of scan, faults) and sends the
    /// events it produced. Call regularly, whether or not bytes arrived.
    pub fn poll<H: TriggerHardware>(&mut self, hw: &mut H, tx: &mut impl FnMut(&[u8])) {
        self.dispatcher.sequencer.poll(hw);
        self.flush_events(tx);
    }

    /// The host went away (USB disconnect or suspend): stop any scan, all
    /// outputs idle, drop a half-uploaded plan and any partial frame. The
    /// scan's end (`Aborted`) stays readable by `GetStatus` after reconnect.
    pub fn host_link_lost<H: TriggerHardware>(&mut self, hw: &mut H) {
        self.dispatcher.sequencer.abort(hw);
        self.dispatcher.upload = None;
        self.rx = FrameAccumulator::new();
        // Nobody is listening: the queued events would only go stale.
        while self.dispatcher.sequencer.pop_event().is_some() {}
    }

    fn flush_events(&mut self, tx: &mut impl FnMut(&[u8])) {
        while let Some(event) = self.dispatcher.sequencer.pop_event() {
            send(&BoardFrame::Event(event), tx);
        }
    }
}

/// Encodes one board frame and hands it to `tx`. Every `BoardFrame` fits a
/// frame (checked by a test), so encoding cannot fail in practice; if it
/// ever did, a `LinkError` is sent instead of nothing.
fn send(frame: &BoardFrame, tx: &mut impl FnMut(&[u8])) {
    let mut buf = [0u8; MAX_FRAME_BYTES];
    match encode_frame(frame, &mut buf) {
        Ok(n) => tx(&buf[..n]),
        Err(error) => {
            if let Ok(n) = encode_frame(&BoardFrame::LinkError(WireError::Frame(error)), &mut buf) {
                tx(&buf[..n]);
            }
        }
    }
}
