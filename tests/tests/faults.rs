//! Faults on the link and the rig, through the real pty: corrupted and
//! truncated frames get an error answer and the link recovers; answers lost
//! on the way back are retried with the same request id; a board that goes
//! silent mid-scan gives the host a timeout error within a bounded time; a
//! camera that misses a trigger is reported missing by the board. Nothing
//! panics: every failure is a typed error.

use std::time::{Duration, Instant};

use hil_sim::board::SimBoardConfig;
use hil_sim::faults::{FaultPlan, MissedTrigger, Noise, StreamFaults};
use integration_tests::{pty_rig, recorded_edges, PtyRig, IMPATIENT, PATIENT};
use protocol::limits::{ns_to_ticks, MAX_FRAME_BYTES};
use protocol::plan::examples;
use protocol::{encode_frame, Event, FrameError, HostFrame, Level, Request, ScanState, WireError};
use slscan::board::{BoardError, ClientConfig, LinkError, Transport};

fn rig(faults: FaultPlan, client: ClientConfig) -> PtyRig {
    pty_rig(SimBoardConfig { seed: 5, faults }, client).expect("simulated board on a pty")
}

/// A valid request frame, as the client would send it.
fn ping_frame(id: u32) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_BYTES];
    let n = encode_frame(
        &HostFrame {
            id,
            request: Request::Ping { nonce: 77 },
        },
        &mut buf,
    )
    .expect("a ping fits a frame");
    buf[..n].to_vec()
}

/// Sends raw bytes down the pty, then a normal request; returns what the
/// board complained about on the way (the client counts `LinkError` frames).
fn raw_then_ping(rig: &mut PtyRig, raw: &[u8]) -> Option<WireError> {
    rig.client
        .transport_mut()
        .send(raw)
        .expect("pty takes bytes");
    let before = rig.client.stats().board_link_errors;
    rig.client.ping(1).expect("the link recovers");
    assert_eq!(
        rig.client.stats().board_link_errors,
        before + 1,
        "one error answer"
    );
    rig.client.stats().last_board_link_error
}

#[test]
fn corrupted_frame_gets_a_crc_error_answer_and_the_link_recovers() {
    let mut rig = rig(FaultPlan::none(), PATIENT);
    let mut frame = ping_frame(900);
    frame[2] ^= 0x01;
    let error = raw_then_ping(&mut rig, &frame);
    assert!(
        matches!(
            error,
            Some(WireError::Frame(
                FrameError::CrcMismatch { .. } | FrameError::Cobs
            ))
        ),
        "{error:?}"
    );
}

#[test]
fn truncated_frame_gets_an_error_answer_and_the_link_recovers() {
    let mut rig = rig(FaultPlan::none(), PATIENT);
    // Half a frame, its end lost: the client's next frame starts with a
    // delimiter, which ends the half frame on the board, so only it is lost.
    let frame = ping_frame(901);
    let error = raw_then_ping(&mut rig, &frame[..frame.len() / 2]);
    assert!(matches!(error, Some(WireError::Frame(_))), "{error:?}");
    // And a frame cut short with its delimiter still there.
    let mut cut = frame[..3].to_vec();
    cut.push(0);
    let error = raw_then_ping(&mut rig, &cut);
    assert!(matches!(error, Some(WireError::Frame(_))), "{error:?}");
}

#[test]
fn oversized_garbage_is_refused_by_size_and_the_link_recovers() {
    let mut rig = rig(FaultPlan::none(), PATIENT);
    let mut garbage = vec![0x5a; MAX_FRAME_BYTES + 100];
    garbage.push(0);
    let error = raw_then_ping(&mut rig, &garbage);
    assert_eq!(
        error,
        Some(WireError::Frame(FrameError::Oversized {
            limit: MAX_FRAME_BYTES as u16
        }))
    );
}

/// Where the first request after the handshake starts in the host's byte
/// stream, measured on a fault-free board.
fn first_request_offset() -> u64 {
    let probe = rig(FaultPlan::none(), PATIENT);
    let offset = probe.board.board().filters().0.bytes_in();
    offset
}

/// `faults` hit the first request after the handshake; the client must
/// recover by re-sending it with the same id.
fn request_recovers_from(faults: StreamFaults) -> PtyRig {
    let mut rig = rig(
        FaultPlan {
            to_board: faults,
            ..FaultPlan::none()
        },
        IMPATIENT,
    );
    let status = rig.client.status().expect("re-sent and answered");
    assert_eq!(status.state, ScanState::Idle);
    let stats = rig.client.stats();
    assert!(stats.retries >= 1, "{stats:?}");
    assert!(
        stats.board_link_errors >= 1,
        "the board said it could not read it"
    );
    rig
}

#[test]
fn bit_flipped_request_is_retried_with_the_same_id_and_succeeds() {
    let at = first_request_offset() + 4;
    let rig = request_recovers_from(StreamFaults {
        flip_bits: [(at, 3)].into(),
        ..StreamFaults::default()
    });
    assert_eq!(rig.board.board().filters().0.flipped(), 1);
}

#[test]
fn request_with_a_dropped_byte_is_retried_and_succeeds() {
    let at = first_request_offset() + 5;
    let rig = request_recovers_from(StreamFaults {
        drop_bytes: [at].into(),
        ..StreamFaults::default()
    });
    assert_eq!(rig.board.board().filters().0.dropped(), 1);
}

#[test]
fn lost_answer_to_start_is_replayed_not_refused() {
    let plan = examples::multiplexed_24_at_5khz(2);
    // Where the board's answer to Start begins in its byte stream: measured
    // on a fault-free board after the same upload and arm.
    let mut probe = rig(FaultPlan::none(), PATIENT);
    probe.client.upload_plan(&plan).expect("upload");
    probe.client.arm().expect("arm");
    let offset = probe.board.board().filters().1.bytes_in();
    drop(probe);

    let mut faults = FaultPlan::none();
    faults.to_host.flip_bits = [(offset + 3, 1)].into();
    // Short timeouts (the lost answer costs one), many attempts (a loaded
    // machine may need more than one).
    let config = ClientConfig {
        attempt_timeout: Duration::from_millis(300),
        attempts: 5,
    };
    let mut rig = rig(faults, config);
    let outcome = rig
        .client
        .run_plan(&plan, 1_000_000, |_| {})
        .expect("a lost answer is retried and the board replays it");
    assert!(outcome.is_clean(), "{outcome:?}");
    let stats = rig.client.stats();
    assert_eq!(stats.corrupt_frames, 1, "{stats:?}");
    assert!(stats.retries >= 1, "{stats:?}");
    // The scan ran exactly once: each edge of the 2 cycles once.
    assert_eq!(recorded_edges(&rig.board).len(), 2 * 25 * 2);
}

#[test]
fn board_silent_mid_scan_gives_a_timeout_error_within_bounded_time() {
    let plan = examples::dual_head_psp(1);
    let hz = protocol::BoardLimits::STM32G474.timer_clock_hz;
    // A fresh board's clock stands at 0 until a scan runs, so the scan
    // starts at the start delay; the board vanishes half-way through.
    let start_tick = ns_to_ticks(1_000_000, hz);
    let half = start_tick + ns_to_ticks(plan.total_ns() / 2, hz);
    let faults = FaultPlan {
        vanish_at_tick: Some(half),
        ..FaultPlan::none()
    };
    let mut rig = rig(faults, IMPATIENT);
    let asked = Instant::now();
    let result = rig.client.run_plan(&plan, 1_000_000, |_| {});
    let waited = asked.elapsed();
    match result {
        Err(BoardError::Link(LinkError::Timeout {
            request, attempts, ..
        })) => {
            assert_eq!(request, "GetStatus");
            assert_eq!(attempts, IMPATIENT.attempts);
        }
        other => panic!("expected a link timeout, got {other:?}"),
    }
    // Nominal: one quiet spell + attempts x timeout = 0.6 s.
    assert!(waited < Duration::from_secs(5), "took {waited:?}");
    let board = rig.board.board();
    assert!(board.has_vanished());
    assert_eq!(board.state(), ScanState::Running, "it died mid-scan");
    let played = board.hardware().recorded().len();
    assert!(
        played > 0 && played < 16 * 2 * 2 * 2,
        "{played} edges played"
    );
}

#[test]
fn board_that_stops_answering_requests_times_out() {
    let faults = FaultPlan {
        to_host: StreamFaults {
            silent_after_frames: Some(1),
            ..StreamFaults::default()
        },
        ..FaultPlan::none()
    };
    let mut rig = rig(faults, IMPATIENT);
    let err = rig.client.info().expect_err("a silent board cannot answer");
    assert!(
        matches!(
            err,
            BoardError::Link(LinkError::Timeout {
                request: "GetInfo",
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn camera_that_misses_a_trigger_is_reported_missing() {
    let plan = examples::multiplexed_24_at_5khz(3);
    let faults = FaultPlan {
        missed_triggers: [MissedTrigger {
            camera: 0,
            trigger_index: 1,
        }]
        .into(),
        ..FaultPlan::none()
    };
    let mut rig = rig(faults, PATIENT);
    let outcome = rig.client.run_plan(&plan, 1_000_000, |_| {}).expect("runs");
    assert_eq!(outcome.state, ScanState::Done);
    assert!(!outcome.is_clean());
    assert_eq!(outcome.report.missing, 2, "{:?}", outcome.report);
    let camera_feedback = plan.heads[0].camera_feedback_channel;
    let missing: Vec<(u32, Level)> = outcome
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::FeedbackMissing {
                feedback_channel,
                cycle,
                level,
                ..
            } if feedback_channel == camera_feedback => Some((cycle, level)),
            _ => None,
        })
        .collect();
    assert_eq!(missing, vec![(1, Level::High), (1, Level::Low)]);
    assert_eq!(
        rig.board.board().hardware().heads()[0]
            .camera
            .exposures()
            .len(),
        2
    );
}

#[test]
fn noisy_link_only_ever_gives_answers_or_link_errors() {
    let noise = Noise {
        drop_ppm: 2_000,
        flip_ppm: 2_000,
        seed: 11,
    };
    let faults = FaultPlan {
        to_board: StreamFaults {
            noise: Some(noise),
            ..StreamFaults::default()
        },
        to_host: StreamFaults {
            noise: Some(Noise { seed: 12, ..noise }),
            ..StreamFaults::default()
        },
        ..FaultPlan::none()
    };
    let board = hil_sim::board::spawn_on_pty(SimBoardConfig { seed: 5, faults }).expect("pty");
    let path = board.path().expect("path").to_path_buf();
    let transport = slscan::board::SerialTransport::open(&path, 115_200).expect("open pty");
    let config = ClientConfig {
        attempt_timeout: Duration::from_millis(200),
        attempts: 3,
    };
    let mut client = slscan::board::BoardClient::new(transport, config);
    let mut answered = 0;
    for nonce in 0..30 {
        match client.ping(nonce) {
            Ok(()) => answered += 1,
            Err(e) => assert!(e.is_link_failure(), "ping {nonce}: {e}"),
        }
    }
    assert!(answered > 15, "only {answered} of 30 pings answered");
}

#[test]
fn board_gone_from_under_the_port_is_a_link_error_not_a_hang() {
    let PtyRig {
        board, mut client, ..
    } = rig(FaultPlan::none(), IMPATIENT);
    client.ping(1).expect("alive");
    // The board's process ends: its side of the pty closes, like a board
    // unplugged from USB.
    board.stop().expect("board loop ended cleanly");
    let asked = Instant::now();
    let err = client.ping(2).expect_err("nobody is there");
    assert!(
        matches!(err, BoardError::Link(LinkError::PortGone { .. })),
        "{err:?}"
    );
    assert!(
        asked.elapsed() < Duration::from_secs(5),
        "{:?}",
        asked.elapsed()
    );
}

#[test]
fn noisy_link_still_runs_every_request_exactly_once() {
    // Corruption both ways through a whole upload and scan: requests are
    // re-sent, lost answers replayed from the board's cache; the board must
    // still have played the plan exactly once.
    let faults = FaultPlan {
        to_board: StreamFaults {
            noise: Some(Noise {
                drop_ppm: 1_000,
                flip_ppm: 1_000,
                seed: 21,
            }),
            ..StreamFaults::default()
        },
        // Answers to BeginPlan and to exposures 3, 8 and 15, and one more
        // frame later (whatever the retries made it), arrive corrupted.
        to_host: StreamFaults {
            flip_frames: [1, 5, 10, 17, 19].into(),
            ..StreamFaults::default()
        },
        ..FaultPlan::none()
    };
    let config = ClientConfig {
        attempt_timeout: Duration::from_millis(200),
        attempts: 6,
    };
    let plan = examples::dual_head_psp(1);
    let board = hil_sim::board::spawn_on_pty(SimBoardConfig { seed: 5, faults }).expect("pty");
    let path = board.path().expect("path").to_path_buf();
    let transport = slscan::board::SerialTransport::open(&path, 115_200).expect("open pty");
    let mut client = slscan::board::BoardClient::new(transport, config);
    client.hello().expect("handshake through the noise");
    let outcome = client
        .run_plan(&plan, 1_000_000, |_| {})
        .expect("the plan runs through the noise");
    assert_eq!(outcome.state, ScanState::Done);
    assert_eq!(outcome.report.expected, outcome.report.on_time);
    let stats = client.stats();
    assert_eq!(stats.corrupt_frames, 5, "{stats:?}");
    assert!(stats.retries >= 5, "{stats:?}");
    // 16 exposures x 2 heads x (camera + projector pulse) x 2 edges, once.
    assert_eq!(recorded_edges(&board).len(), 16 * 2 * 2 * 2);
}

#[test]
fn projector_slower_than_its_profile_is_caught_lighting_outside_the_exposure() {
    // 3 us of extra DMD latency: every projector edge is late (beyond the
    // 100 ns jitter, within the late window), and the last of the 24
    // patterns, which had 1.5 us to spare, now ends after the exposure.
    let faults = FaultPlan {
        projector_lag_ns: [(0, 3_000)].into(),
        ..FaultPlan::none()
    };
    let mut rig = rig(faults, PATIENT);
    let plan = examples::multiplexed_24_at_5khz(3);
    let outcome = rig.client.run_plan(&plan, 1_000_000, |_| {}).expect("runs");
    assert_eq!(outcome.state, ScanState::Done);
    let r = outcome.report;
    assert_eq!(r.late, 3 * 24 * 2, "{r:?}");
    assert_eq!((r.patterns_checked, r.out_of_window), (3 * 24, 3), "{r:?}");
    let outside: Vec<(u32, u16)> = outcome
        .events
        .iter()
        .filter_map(|e| match *e {
            Event::PatternOutsideExposure { cycle, slot, .. } => Some((cycle, slot)),
            _ => None,
        })
        .collect();
    assert_eq!(outside, vec![(0, 23), (1, 23), (2, 23)]);
    assert!(!outcome.is_clean());
}
