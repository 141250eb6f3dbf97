//! The link and sequencer against a scripted fake of `TriggerHardware`:
//! request handling, refusals, frame errors, retries, feedback checking.

use board_core::{Capture, EdgeTable, Link, TriggerHardware};
use protocol::limits::MAX_FRAME_BYTES;
use protocol::plan::examples;
use protocol::{
    decode_payload, encode_frame, BoardFrame, BoardLimits, DeviceInfo, Event, FirmwareVersion,
    FrameAccumulator, FrameError, HardwareFault, HostFrame, Level, Request, ResetCause, Response,
    ScanPlan, ScanState, WireError, PROTOCOL_VERSION,
};

/// Records what the core asked of it; time and captures are scripted.
#[derive(Default)]
struct FakeHardware {
    now: u64,
    loaded: Option<EdgeTable>,
    started: Option<(u64, u32)>,
    stops: u32,
    captures: std::collections::VecDeque<Capture>,
    fault: Option<HardwareFault>,
}

impl TriggerHardware for FakeHardware {
    fn load(&mut self, table: &EdgeTable) -> Result<(), HardwareFault> {
        self.loaded = Some(table.clone());
        Ok(())
    }
    fn start(&mut self, start_tick: u64, repeat_count: u32) -> Result<(), HardwareFault> {
        self.started = Some((start_tick, repeat_count));
        Ok(())
    }
    fn stop(&mut self) {
        self.stops += 1;
    }
    fn now_ticks(&self) -> u64 {
        self.now
    }
    fn pop_capture(&mut self) -> Option<Capture> {
        self.captures.pop_front()
    }
    fn fault(&self) -> Option<HardwareFault> {
        self.fault
    }
}

fn info() -> DeviceInfo {
    DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id: 42,
        limits: BoardLimits::STM32G474,
        reset_cause: ResetCause::PowerOn,
    }
}

/// A link, a fake, and a host-side decoder of what the link sent.
struct Bench {
    link: Link,
    hw: FakeHardware,
    rx: FrameAccumulator,
}

impl Bench {
    fn new() -> Self {
        Bench {
            link: Link::new(info()),
            hw: FakeHardware::default(),
            rx: FrameAccumulator::new(),
        }
    }

    fn send_bytes(&mut self, bytes: &[u8]) -> Vec<BoardFrame> {
        let mut sent = Vec::new();
        self.link.receive(bytes, &mut self.hw, &mut |frame: &[u8]| {
            sent.extend_from_slice(frame)
        });
        self.decode(&sent)
    }

    fn poll(&mut self) -> Vec<BoardFrame> {
        let mut sent = Vec::new();
        self.link.poll(&mut self.hw, &mut |frame: &[u8]| {
            sent.extend_from_slice(frame)
        });
        self.decode(&sent)
    }

    fn decode(&mut self, bytes: &[u8]) -> Vec<BoardFrame> {
        let mut out = Vec::new();
        self.rx.feed(bytes, |f| {
            out.push(f.and_then(decode_payload::<BoardFrame>).unwrap())
        });
        out
    }

    /// Sends one request; returns its response (events that follow are dropped).
    fn ask(&mut self, id: u32, request: Request) -> Response {
        let mut buf = [0u8; MAX_FRAME_BYTES];
        let n = encode_frame(&HostFrame { id, request }, &mut buf).unwrap();
        let frames = self.send_bytes(&buf[..n]);
        match frames.into_iter().next() {
            Some(BoardFrame::Response { id: got, response }) => {
                assert_eq!(got, id);
                response
            }
            other => panic!("expected a response, got {other:?}"),
        }
    }

    fn upload(&mut self, plan: &ScanPlan) -> Response {
        assert_eq!(
            self.ask(1, Request::BeginPlan(plan.header())),
            Response::PlanBegun
        );
        for i in 0..plan.exposures.len() {
            let exposure = plan.wire_exposure(i).unwrap();
            let r = self.ask(
                10 + i as u32,
                Request::AddExposure {
                    index: i as u16,
                    exposure,
                },
            );
            assert_eq!(r, Response::ExposureAdded { index: i as u16 });
        }
        self.ask(1000, Request::CommitPlan)
    }
}

fn refused(r: Response) -> WireError {
    match r {
        Response::Refused(e) => e,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn hello_checks_the_protocol_version() {
    let mut b = Bench::new();
    assert_eq!(
        b.ask(
            1,
            Request::Hello {
                protocol_version: PROTOCOL_VERSION
            }
        ),
        Response::Hello(info())
    );
    assert_eq!(
        refused(b.ask(
            2,
            Request::Hello {
                protocol_version: PROTOCOL_VERSION + 1
            }
        )),
        WireError::UnsupportedVersion {
            board: PROTOCOL_VERSION,
            host: PROTOCOL_VERSION + 1
        }
    );
}

#[test]
fn a_plan_uploads_arms_starts_and_aborts() {
    let mut b = Bench::new();
    let plan = examples::multiplexed_24_at_5khz(2);
    let Response::PlanCommitted(summary) = b.upload(&plan) else {
        panic!("not committed")
    };
    assert_eq!(summary.edges_per_cycle, 50);
    assert_eq!(summary.repeat_count, 2);
    assert_eq!(b.ask(2000, Request::Arm), Response::Armed);
    assert_eq!(b.hw.loaded.as_ref().unwrap().edges().len(), 50);
    b.hw.now = 1_000;
    // A 1 us start is moved out to the board's 100 us floor.
    assert_eq!(
        b.ask(2001, Request::Start { delay_ns: 1_000 }),
        Response::Started { start_tick: 18_000 }
    );
    assert_eq!(b.hw.started, Some((18_000, 2)));
    assert_eq!(
        refused(b.ask(2002, Request::CommitPlan)),
        WireError::NoPlanBegun
    );
    let stops = b.hw.stops;
    assert!(matches!(b.ask(2003, Request::Abort), Response::Aborted(_)));
    assert_eq!(b.hw.stops, stops + 1);
    let Response::Status(status) = b.ask(2004, Request::GetStatus) else {
        panic!()
    };
    assert_eq!(status.state, ScanState::Aborted);
}

#[test]
fn out_of_order_requests_are_refused_with_reasons() {
    let mut b = Bench::new();
    let plan = examples::dual_head_psp(1);
    assert_eq!(refused(b.ask(1, Request::Arm)), WireError::NoPlan);
    assert_eq!(
        refused(b.ask(2, Request::Start { delay_ns: 0 })),
        WireError::BadState {
            state: ScanState::Idle
        }
    );
    let exposure = plan.wire_exposure(0).unwrap();
    assert_eq!(
        refused(b.ask(
            3,
            Request::AddExposure {
                index: 0,
                exposure: exposure.clone()
            }
        )),
        WireError::NoPlanBegun
    );
    b.ask(4, Request::BeginPlan(plan.header()));
    assert_eq!(
        refused(b.ask(5, Request::AddExposure { index: 3, exposure })),
        WireError::ExposureOutOfSequence {
            expected: 0,
            received: 3
        }
    );
    assert_eq!(
        refused(b.ask(6, Request::CommitPlan)),
        WireError::PlanIncomplete {
            announced: 16,
            received: 0
        }
    );
    let mut bad = examples::multiplexed_24_at_5khz(1);
    bad.heads[0].projector = protocol::ProjectorModel::Dlpc350;
    assert!(matches!(
        refused(b.upload(&bad)),
        WireError::Plan(protocol::PlanError::PatternPeriodTooShort { .. })
    ));
}

/// Issue 21: a plan with more heads than the board reports lines for is
/// refused at commit, in heads (not as an out-of-range channel), and the
/// board then takes one within its lines.
#[test]
fn more_heads_than_the_board_has_lines_are_refused_in_heads() {
    let mut b = Bench::new();
    assert_eq!(
        refused(b.upload(&examples::all_heads_psp(3, 1))),
        WireError::Plan(protocol::PlanError::TooManyHeadsForBoard {
            heads: 3,
            output_channels: 4,
            feedback_channels: 4,
            max_heads: 2
        })
    );
    assert!(matches!(
        b.upload(&examples::all_heads_psp(2, 1)),
        Response::PlanCommitted(_)
    ));
}

#[test]
fn corrupt_and_truncated_frames_get_a_link_error_then_the_link_recovers() {
    let mut b = Bench::new();
    let mut buf = [0u8; MAX_FRAME_BYTES];
    let n = encode_frame(
        &HostFrame {
            id: 5,
            request: Request::Ping { nonce: 9 },
        },
        &mut buf,
    )
    .unwrap();
    let mut corrupt = buf[..n].to_vec();
    corrupt[1] ^= 0x04;
    let got = b.send_bytes(&corrupt);
    assert!(
        matches!(got[..], [BoardFrame::LinkError(WireError::Frame(_))]),
        "{got:?}"
    );
    let got = b.send_bytes(&[&buf[..n / 2], &[0u8][..]].concat());
    assert!(
        matches!(got[..], [BoardFrame::LinkError(WireError::Frame(_))]),
        "{got:?}"
    );
    let got = b.send_bytes(&[0x42; MAX_FRAME_BYTES + 5]);
    assert!(got.is_empty());
    let got = b.send_bytes(&[0]);
    assert_eq!(
        got,
        vec![BoardFrame::LinkError(WireError::Frame(
            FrameError::Oversized { limit: 512 }
        ))]
    );
    assert_eq!(
        b.ask(6, Request::Ping { nonce: 10 }),
        Response::Pong { nonce: 10 }
    );
}

#[test]
fn a_retried_request_is_answered_again_not_run_twice() {
    let mut b = Bench::new();
    let plan = examples::flood_preliminaries(1);
    b.ask(1, Request::BeginPlan(plan.header()));
    let exposure = plan.wire_exposure(0).unwrap();
    let first = b.ask(
        2,
        Request::AddExposure {
            index: 0,
            exposure: exposure.clone(),
        },
    );
    let retry = b.ask(
        2,
        Request::AddExposure {
            index: 0,
            exposure: exposure.clone(),
        },
    );
    assert_eq!(first, retry);
    assert_eq!(first, Response::ExposureAdded { index: 0 });
    // A new id with the same content does run, and is out of sequence.
    assert_eq!(
        refused(b.ask(3, Request::AddExposure { index: 0, exposure })),
        WireError::ExposureOutOfSequence {
            expected: 1,
            received: 0
        }
    );
}

/// Runs the 24-pattern plan once on the fake with scripted feedback:
/// `feedback(expected_tick, channel, level) -> Option<tick>`.
fn scripted_scan(
    feedback: impl Fn(u64, u8, Level) -> Option<u64>,
) -> (protocol::ScanReport, Vec<Event>) {
    let mut b = Bench::new();
    let plan = examples::multiplexed_24_at_5khz(1);
    b.upload(&plan);
    b.ask(2000, Request::Arm);
    let Response::Started { start_tick } = b.ask(2001, Request::Start { delay_ns: 0 }) else {
        panic!()
    };
    let table = b.hw.loaded.clone().unwrap();
    let lines = [(0u8, 170u64), (1u8, 255u64)]; // latencies at 170 MHz: 1 us, 1.5 us
    let mut captures: Vec<Capture> = Vec::new();
    for e in table.edges() {
        let (_, lat) = lines[e.channel as usize];
        let expected = start_tick + e.tick as u64 + lat;
        if let Some(tick) = feedback(expected, e.channel, e.level) {
            captures.push(Capture {
                feedback_channel: e.channel,
                level: e.level,
                tick,
            });
        }
    }
    captures.sort_by_key(|c| c.tick);
    b.hw.captures.extend(captures);
    b.hw.now = start_tick + table.total_ticks() + 10_000_000;
    let mut events = Vec::new();
    for _ in 0..4 {
        for f in b.poll() {
            if let BoardFrame::Event(e) = f {
                events.push(e);
            }
        }
    }
    let Response::Status(status) = b.ask(3000, Request::GetStatus) else {
        panic!()
    };
    assert_eq!(status.state, ScanState::Done);
    (status.report, events)
}

#[test]
fn feedback_on_time_is_counted_with_its_error() {
    let (report, events) = scripted_scan(|t, _, _| Some(t + 3));
    assert_eq!(
        (
            report.expected,
            report.on_time,
            report.late,
            report.missing,
            report.unexpected
        ),
        (50, 50, 0, 0, 0)
    );
    assert_eq!(report.worst_error_ticks, 3);
    assert!(matches!(
        events.last(),
        Some(Event::ScanFinished {
            state: ScanState::Done,
            ..
        })
    ));
}

#[test]
fn late_missing_and_unexpected_feedback_are_reported() {
    // Projector pulse 5 rises 500 ticks (2.9 us) late (inside its 10 us pulse), camera's falling edge
    // never comes, and one extra camera edge appears far from any expected.
    let (report, events) = scripted_scan(|t, ch, level| match (ch, level) {
        (1, Level::Low) => None,
        (0, Level::High) if t > 5 * 34_000 && t < 6 * 34_000 => Some(t + 500),
        _ => Some(t),
    });
    assert_eq!(report.late, 1, "{report:?}");
    assert_eq!(report.missing, 1, "{report:?}");
    assert!(events.iter().any(|e| matches!(
        e,
        Event::FeedbackLate {
            feedback_channel: 0,
            ..
        }
    )));
    assert!(events.iter().any(|e| matches!(
        e,
        Event::FeedbackMissing {
            feedback_channel: 1,
            level: Level::Low,
            ..
        }
    )));
    let (report, _) = scripted_scan(|t, ch, level| {
        if (ch, level) == (1, Level::High) {
            Some(t + 500_000)
        } else {
            Some(t)
        }
    });
    // 500 000 ticks after the exposure start is past half the exposure: not
    // attributable, so the rise is missing and the capture unexpected.
    assert_eq!((report.missing, report.unexpected), (1, 1), "{report:?}");
}

#[test]
fn early_feedback_is_attributed_not_missing() {
    // Every camera edge 200 ticks (1.2 us) early: outside the 18-tick
    // tolerance, inside the 255-tick latency (feedback cannot come sooner).
    let (report, events) = scripted_scan(|t, ch, _| Some(if ch == 1 { t - 200 } else { t }));
    assert_eq!(
        (report.late, report.missing, report.unexpected),
        (2, 0, 0),
        "{report:?}"
    );
    assert_eq!(report.worst_error_ticks, 200);
    assert!(events.iter().any(|e| matches!(e, Event::FeedbackLate { measured_tick, expected_tick, .. } if measured_tick < expected_tick)));
    // 300 ticks early would precede the trigger itself: not attributable.
    let (report, _) = scripted_scan(|t, ch, level| {
        Some(if (ch, level) == (1, Level::High) {
            t - 300
        } else {
            t
        })
    });
    assert_eq!((report.missing, report.unexpected), (1, 1), "{report:?}");
}

#[test]
fn a_pattern_outside_its_measured_exposure_is_reported() {
    // Start tick 17 000 (the 100 us floor). The last pattern's light ends
    // 255 ticks before the exposure's: an exposure-active fall 200 ticks
    // early keeps it inside...
    let early_fall = |t: u64, ch: u8, level: Level| {
        Some(if (ch, level) == (1, Level::Low) {
            t - 200
        } else {
            t
        })
    };
    let (report, _) = scripted_scan(early_fall);
    assert_eq!(
        (report.patterns_checked, report.out_of_window),
        (24, 0),
        "{report:?}"
    );
    // ... but not if the last trigger-out also rises 100 ticks late.
    let (report, events) = scripted_scan(|t, ch, level| {
        let late = (ch, level) == (0, Level::High) && t > 17_000 + 782_000;
        early_fall(t, ch, level).map(|t| if late { t + 100 } else { t })
    });
    assert_eq!(
        (report.patterns_checked, report.out_of_window),
        (24, 1),
        "{report:?}"
    );
    assert!(events.iter().any(|e| matches!(
        e,
        Event::PatternOutsideExposure {
            head: 0,
            cycle: 0,
            exposure: 0,
            slot: 23,
            ..
        }
    )));
}

#[test]
fn a_hardware_fault_stops_the_scan() {
    let mut b = Bench::new();
    b.upload(&examples::flood_preliminaries(1));
    b.ask(1, Request::Arm);
    b.ask(2, Request::Start { delay_ns: 0 });
    b.hw.fault = Some(HardwareFault::EdgeUnderrun { channel: 1 });
    let stops = b.hw.stops;
    let events = b.poll();
    assert!(events.iter().any(|f| matches!(
        f,
        BoardFrame::Event(Event::ScanFinished {
            state: ScanState::Faulted,
            ..
        })
    )));
    assert!(events.iter().any(|f| matches!(
        f,
        BoardFrame::Event(Event::HardwareFault {
            fault: HardwareFault::EdgeUnderrun { channel: 1 },
            ..
        })
    )));
    assert_eq!(b.hw.stops, stops + 1);
}

#[test]
fn losing_the_host_stops_the_scan() {
    let mut b = Bench::new();
    b.upload(&examples::flood_preliminaries(1));
    b.ask(1, Request::Arm);
    b.ask(2, Request::Start { delay_ns: 0 });
    b.link.host_link_lost(&mut b.hw);
    assert_eq!(b.link.dispatcher().sequencer().state(), ScanState::Aborted);
    assert!(b.poll().is_empty());
}
