//! Any plan (valid or not) and every message survive the wire: postcard,
//! CRC, COBS, arbitrary chunking, the accumulator, and back.

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use protocol::limits::{BoardLimits, MAX_FRAME_BYTES, MAX_SLOTS_PER_CYCLE, MAX_SLOTS_PER_EXPOSURE};
use protocol::{
    decode_payload, encode_frame, BoardFrame, BoardStatus, CameraModel, DeviceInfo, Event,
    FirmwareVersion, FrameAccumulator, HeadConfig, HeadSet, HostFrame, Level, PatternSlot,
    ProjectorModel, Request, ResetCause, Response, ScanPlan, ScanReport, ScanState,
};

fn head() -> impl Strategy<Value = HeadConfig> {
    (any::<bool>(), any::<bool>(), any::<[u8; 4]>()).prop_map(|(p, c, ch)| HeadConfig {
        projector: if p {
            ProjectorModel::Dlpc350
        } else {
            ProjectorModel::Dlpc900
        },
        camera: if c {
            CameraModel::Mono6Mp
        } else {
            CameraModel::Colour208Hz
        },
        projector_trigger_channel: ch[0],
        camera_trigger_channel: ch[1],
        projector_feedback_channel: ch[2],
        camera_feedback_channel: ch[3],
    })
}

fn slot() -> impl Strategy<Value = PatternSlot> {
    (any::<u16>(), any::<u32>(), any::<u32>()).prop_map(|(pattern_index, offset_ns, display_ns)| {
        PatternSlot {
            pattern_index,
            offset_ns,
            display_ns,
        }
    })
}

/// Any plan the capacities allow, valid or not.
fn plan() -> impl Strategy<Value = ScanPlan> {
    (
        prop::collection::vec(head(), 1..=2),
        any::<u32>(),
        any::<u32>(),
        any::<u32>(),
        prop::collection::vec(
            (
                any::<u8>(),
                any::<u32>(),
                any::<u32>(),
                prop::collection::vec(slot(), 0..=MAX_SLOTS_PER_EXPOSURE),
            ),
            0..=12,
        ),
    )
        .prop_map(|(heads, repeat, period, margin, exposures)| {
            let mut plan = ScanPlan::new(&heads, repeat, period, margin).unwrap();
            for (h, start, duration, slots) in exposures {
                if plan.slots.len() + slots.len() <= MAX_SLOTS_PER_CYCLE {
                    plan.push_exposure(HeadSet(h), start, duration, &slots)
                        .unwrap();
                }
            }
            plan
        })
}

/// Encodes every frame of a plan upload, ids from `first_id`.
fn upload_frames(plan: &ScanPlan, first_id: u32) -> Vec<HostFrame> {
    let mut frames = vec![HostFrame {
        id: first_id,
        request: Request::BeginPlan(plan.header()),
    }];
    for i in 0..plan.exposures.len() {
        frames.push(HostFrame {
            id: first_id.wrapping_add(1 + i as u32),
            request: Request::AddExposure {
                index: i as u16,
                exposure: plan.wire_exposure(i).unwrap(),
            },
        });
    }
    frames
}

fn encode_all<T: serde::Serialize>(messages: &[T]) -> Vec<u8> {
    let mut bytes = Vec::new();
    for m in messages {
        let mut buf = [0u8; MAX_FRAME_BYTES];
        let n = encode_frame(m, &mut buf).unwrap();
        assert!(n <= MAX_FRAME_BYTES);
        bytes.extend_from_slice(&buf[..n]);
    }
    bytes
}

fn decode_all<T: serde::de::DeserializeOwned>(bytes: &[u8], chunk: usize) -> Vec<T> {
    let mut acc = FrameAccumulator::new();
    let mut out = Vec::new();
    for piece in bytes.chunks(chunk.max(1)) {
        acc.feed(piece, |frame| {
            out.push(frame.and_then(decode_payload::<T>).unwrap())
        });
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    #[test]
    fn any_plan_roundtrips_through_the_wire(plan in plan(), first_id in any::<u32>(), chunk in 1usize..700) {
        let frames = upload_frames(&plan, first_id);
        let bytes = encode_all(&frames);
        let decoded: Vec<HostFrame> = decode_all(&bytes, chunk);
        prop_assert_eq!(&decoded, &frames);
        let Request::BeginPlan(header) = &decoded[0].request else { panic!("first frame is the header") };
        let mut rebuilt = ScanPlan::from_header(header);
        for f in &decoded[1..] {
            let Request::AddExposure { exposure, .. } = &f.request else { panic!("exposure frame") };
            rebuilt.push_wire_exposure(exposure).unwrap();
        }
        prop_assert_eq!(rebuilt, plan);
    }

    #[test]
    fn reports_and_events_roundtrip(counts in any::<[u32; 11]>(), tick in any::<u64>(), id in any::<u32>()) {
        let report = ScanReport {
            cycles: counts[0], expected: counts[1], on_time: counts[2], late: counts[3],
            missing: counts[4], unexpected: counts[5], worst_error_ticks: counts[6], events_dropped: counts[7],
            patterns_checked: counts[8], out_of_window: counts[9], patterns_unchecked: counts[10],
        };
        let frames = [
            BoardFrame::Response { id, response: Response::Status(BoardStatus {
                state: ScanState::Running, now_tick: tick, plan_loaded: true, report }) },
            BoardFrame::Event(Event::ScanFinished { state: ScanState::Done, report }),
            BoardFrame::Event(Event::FeedbackLate {
                feedback_channel: counts[0] as u8, level: Level::High, cycle: counts[1],
                expected_tick: tick, measured_tick: tick.wrapping_add(counts[2] as u64) }),
            BoardFrame::Response { id, response: Response::Started { start_tick: tick } },
        ];
        let decoded: Vec<BoardFrame> = decode_all(&encode_all(&frames), 7);
        prop_assert_eq!(&decoded[..], &frames[..]);
    }
}

/// The largest request (an exposure with every slot at its widest varint)
/// and the largest answers fit one frame.
#[test]
fn worst_case_messages_fit_one_frame() {
    let slot = PatternSlot {
        pattern_index: u16::MAX,
        offset_ns: u32::MAX,
        display_ns: u32::MAX,
    };
    let mut plan = ScanPlan::new(&[], u32::MAX, u32::MAX, u32::MAX).unwrap();
    plan.push_exposure(
        HeadSet(u8::MAX),
        u32::MAX,
        u32::MAX,
        &[slot; MAX_SLOTS_PER_EXPOSURE],
    )
    .unwrap();
    let big = HostFrame {
        id: u32::MAX,
        request: Request::AddExposure {
            index: u16::MAX,
            exposure: plan.wire_exposure(0).unwrap(),
        },
    };
    let info = DeviceInfo {
        protocol_version: u16::MAX,
        firmware_version: FirmwareVersion {
            major: u16::MAX,
            minor: u16::MAX,
            patch: u16::MAX,
        },
        board_id: u64::MAX,
        limits: BoardLimits {
            timer_clock_hz: u32::MAX,
            output_channels: u8::MAX,
            feedback_channels: u8::MAX,
            max_frame_bytes: u16::MAX,
            max_exposures: u16::MAX,
            max_slots_per_cycle: u16::MAX,
            max_repeat_count: u32::MAX,
            min_edge_spacing_ticks: u32::MAX,
            min_start_delay_ticks: u32::MAX,
        },
        reset_cause: ResetCause::Watchdog,
    };
    let mut buf = [0u8; MAX_FRAME_BYTES];
    assert!(encode_frame(&big, &mut buf).unwrap() <= MAX_FRAME_BYTES);
    let answer = BoardFrame::Response {
        id: u32::MAX,
        response: Response::Hello(info),
    };
    let n = encode_frame(&answer, &mut buf).unwrap();
    assert!(n <= MAX_FRAME_BYTES);
    assert_eq!(decode_all::<BoardFrame>(&buf[..n], 3), vec![answer]);
}
