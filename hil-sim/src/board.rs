//! The simulated sync board: the firmware's own `board_core::Link` driving
//! [`SimHardware`] on the virtual 170 MHz clock, with fault injection on its
//! serial bytes. Sans-I/O: [`serve()`] connects it to a pty or to channels.
//!
//! ```text
//! host bytes --to_board faults--> Link::receive --> Dispatcher --> SimHardware
//!                                                                  (devices, clock)
//! host <--to_host faults-- output queue <-- frames <-- Link::poll <--+
//! ```
//!
//! Virtual time moves only while a scan runs, edge by edge
//! ([`SimHardware::next_event_tick`]), never with the wall clock, so a
//! scan's timeline (and every tick the board reports) is the same on every
//! run and every machine. While idle the clock stands still.
//!
//! The simulated rig follows the plan: when a plan is committed, the heads
//! it names (projector and camera models, wiring) are built from their
//! profiles, with the fault plan's missed triggers, and their jitter seeded
//! from the board seed and the head index; each DMD shows its patterns for
//! the plan's `display_ns`, as a host programs a real DMD's pattern table.
//! The board learns the plan by reading the upload as its dispatcher does
//! (same order and retry rules) and checks that it compiles to the very
//! table the dispatcher committed.

pub mod port;
mod rig;
pub mod serve;

use std::collections::VecDeque;

use board_core::{Link, TriggerHardware};
use protocol::limits::MAX_HEADS;
use protocol::{
    BoardLimits, DeviceInfo, FirmwareVersion, HeadConfig, ResetCause, ScanState, PROTOCOL_VERSION,
};

use crate::faults::{ByteFilter, FaultPlan};
use crate::sim_hardware::{SimHardware, SimHead};

pub use port::{BoardPort, ChannelPort, PortError};
pub use serve::{serve, spawn_board_on_pty, spawn_on_channels, spawn_on_pty, SimBoardHandle};

/// How to build a simulated board.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SimBoardConfig {
    /// Seed of every device's jitter.
    pub seed: u64,
    /// Faults to inject.
    pub faults: FaultPlan,
}

/// Steps per virtual second once a scan has played all its edges but the
/// feedback check still waits out its late windows: 1 ms steps.
const TAIL_STEPS_PER_S: u64 = 1_000;

/// Output bytes held before the board pauses its scan: a host that stops
/// reading stalls virtual time instead of growing the queue without end.
const MAX_QUEUED_OUTPUT: usize = 16 * 1024;

/// The simulated board: link, hardware, devices, faults, output queue.
#[derive(Debug)]
pub struct SimBoard {
    config: SimBoardConfig,
    link: Link,
    hw: SimHardware,
    to_board: ByteFilter,
    to_host: ByteFilter,
    output: VecDeque<u8>,
    // The rig follows the plan: the upload as the dispatcher reads it,
    // applied when the board answers `PlanCommitted`.
    upload: rig::UploadReader,
    rig_heads: Vec<HeadConfig>,
    limits: BoardLimits,
}

impl SimBoard {
    /// A board at virtual tick 0, idle, no plan: the STM32G474 sync board
    /// (4 trigger lines, 2 heads).
    pub fn new(config: SimBoardConfig) -> Self {
        Self::with_limits(config, BoardLimits::STM32G474)
    }

    /// A board with other `limits` than the STM32G474's, e.g. 8 trigger and
    /// 8 feedback lines for rigs of 3 or 4 heads (issue 21): it reports them
    /// in `DeviceInfo` and validates plans against them.
    pub fn with_limits(config: SimBoardConfig, limits: BoardLimits) -> Self {
        let heads = (0..MAX_HEADS)
            .map(|_| SimHead::from_profiles(rig::ABSENT_HEAD, 0))
            .collect();
        let to_board = ByteFilter::new(config.faults.to_board.clone());
        let to_host = ByteFilter::new(config.faults.to_host.clone());
        Self {
            link: Link::new(sim_device_info(sim_board_id(config.seed), limits)),
            hw: SimHardware::new(limits, heads),
            to_board,
            to_host,
            output: VecDeque::new(),
            upload: rig::UploadReader::default(),
            rig_heads: Vec::new(),
            limits,
            config,
        }
    }

    /// What the simulated board (of [`SimBoard::new`]) tells the host about
    /// itself.
    pub fn device_info(seed: u64) -> DeviceInfo {
        sim_device_info(sim_board_id(seed), BoardLimits::STM32G474)
    }

    /// The configuration it was built with.
    pub fn config(&self) -> &SimBoardConfig {
        &self.config
    }

    /// The simulated hardware: clock, recorded output edges and captures
    /// (since the last plan commit), device logs.
    pub fn hardware(&self) -> &SimHardware {
        &self.hw
    }

    /// The hardware, mutably (clear its logs between scans).
    pub fn hardware_mut(&mut self) -> &mut SimHardware {
        &mut self.hw
    }

    /// The heads of the simulated rig (those of the last committed plan).
    pub fn rig_heads(&self) -> &[HeadConfig] {
        &self.rig_heads
    }

    /// The sequencer's state.
    pub fn state(&self) -> ScanState {
        self.link.dispatcher().sequencer().state()
    }

    /// Byte counters of the fault filters: (to board, to host).
    pub fn filters(&self) -> (&ByteFilter, &ByteFilter) {
        (&self.to_board, &self.to_host)
    }

    /// Whether the board has vanished (fault `vanish_at_tick` reached).
    pub fn has_vanished(&self) -> bool {
        self.config
            .faults
            .vanish_at_tick
            .is_some_and(|tick| self.hw.now_ticks() >= tick)
    }

    /// Bytes from the host, any chunking.
    pub fn receive(&mut self, bytes: &[u8]) {
        if self.has_vanished() {
            return;
        }
        let mut survived = Vec::with_capacity(bytes.len());
        self.to_board.apply(bytes, &mut survived);
        self.upload.read(&survived);
        let mut frames = Vec::new();
        self.link
            .receive(&survived, &mut self.hw, &mut |f| frames.push(f.to_vec()));
        self.send(frames);
    }

    /// Whether [`SimBoard::step`] would move virtual time now: a scan runs
    /// and the host is keeping up with the output. A vanished board is
    /// frozen: nothing it did after could reach anyone.
    pub fn can_step(&self) -> bool {
        self.state() == ScanState::Running
            && self.output.len() < MAX_QUEUED_OUTPUT
            && !self.has_vanished()
    }

    /// Moves virtual time to the next thing that happens in the running scan
    /// (an output edge or a capture; after the last, 1 ms at a time) and lets
    /// the sequencer check it. Returns false when no scan is running.
    pub fn step(&mut self) -> bool {
        if !self.can_step() {
            return false;
        }
        let now = self.hw.now_ticks();
        let mut next = self
            .hw
            .next_event_tick()
            .unwrap_or(now + self.hw.clock().timer_clock_hz() as u64 / TAIL_STEPS_PER_S)
            .max(now);
        if let Some(vanish) = self.config.faults.vanish_at_tick.filter(|&t| t > now) {
            // Stop exactly there, so the board falls silent at that tick.
            next = next.min(vanish);
        }
        self.hw.advance_to(next);
        let mut frames = Vec::new();
        self.link
            .poll(&mut self.hw, &mut |f| frames.push(f.to_vec()));
        self.send(frames);
        true
    }

    /// Runs the current scan until it ends or the output queue fills.
    pub fn run_scan(&mut self) {
        while self.step() {}
    }

    /// Bytes waiting for the host.
    pub fn output(&self) -> &VecDeque<u8> {
        &self.output
    }

    /// Removes `n` bytes the port has taken from the front of the output.
    pub fn consume_output(&mut self, n: usize) {
        self.output.drain(..n.min(self.output.len()));
    }

    /// Queues frames for the host through the to-host faults, and applies a
    /// committed plan's heads to the rig.
    fn send(&mut self, frames: Vec<Vec<u8>>) {
        if self.has_vanished() {
            return;
        }
        let mut filtered = Vec::new();
        for frame in frames {
            if rig::answers_commit(&frame) {
                self.rebuild_rig();
            }
            filtered.clear();
            self.to_host.apply(&frame, &mut filtered);
            self.output.extend(filtered.iter().copied());
        }
    }

    /// Builds the rig for the plan just committed. Only runs when a commit
    /// succeeded, which the sequencer allows only while no scan is armed or
    /// running, so no device is swapped mid-scan. The edge and capture logs
    /// restart too, so a long-serving board keeps only the current plan's
    /// scans.
    fn rebuild_rig(&mut self) {
        let Some(plan) = self.upload.take_plan() else {
            return;
        };
        self.hw.clear_log();
        let committed = self.link.dispatcher().sequencer().table();
        let heads = rig::build_heads(&plan, committed, &self.config, &self.limits);
        for (slot, head) in self.hw.heads_mut().iter_mut().zip(heads) {
            *slot = head;
        }
        self.rig_heads = plan.heads.to_vec();
    }
}

/// Board id of the simulated board of seed `seed`: "SIM" marked, the seed's
/// low 32 bits.
fn sim_board_id(seed: u64) -> u64 {
    0x5157_0000_0000_0000 | (seed & 0xffff_ffff)
}

/// Device info of a simulated board (board-core firmware 0.1.0 on a virtual
/// clock): the one literal the simulated board and the soak share.
pub fn sim_device_info(board_id: u64, limits: BoardLimits) -> DeviceInfo {
    DeviceInfo {
        protocol_version: PROTOCOL_VERSION,
        firmware_version: FirmwareVersion {
            major: 0,
            minor: 1,
            patch: 0,
        },
        board_id,
        limits,
        reset_cause: ResetCause::Simulated,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::faults::{MissedTrigger, StreamFaults};
    use protocol::limits::MAX_FRAME_BYTES;
    use protocol::plan::examples;
    use protocol::{
        decode_payload, encode_frame, BoardFrame, Event, FrameAccumulator, HostFrame,
        ProjectorModel, Request, Response, ScanPlan, WireError,
    };

    /// Sends one request and returns every frame the board answered with.
    fn call(board: &mut SimBoard, id: u32, request: Request) -> Vec<BoardFrame> {
        let mut buf = [0u8; MAX_FRAME_BYTES];
        let n = encode_frame(&HostFrame { id, request }, &mut buf).unwrap();
        board.receive(&buf[..n]);
        drain(board)
    }

    fn drain(board: &mut SimBoard) -> Vec<BoardFrame> {
        let bytes: Vec<u8> = board.output().iter().copied().collect();
        board.consume_output(bytes.len());
        let mut acc = FrameAccumulator::new();
        let mut frames = Vec::new();
        acc.feed(&bytes, |f| {
            frames.push(f.and_then(decode_payload::<BoardFrame>).unwrap())
        });
        frames
    }

    fn response(frames: &[BoardFrame], want: u32) -> Response {
        frames
            .iter()
            .find_map(|f| match f {
                BoardFrame::Response { id, response } if *id == want => Some(response.clone()),
                _ => None,
            })
            .unwrap_or_else(|| panic!("no response to {want} in {frames:?}"))
    }

    /// Uploads, arms and starts `plan`; returns the start tick.
    fn start(board: &mut SimBoard, plan: &ScanPlan) -> u64 {
        call(board, 1, Request::BeginPlan(plan.header()));
        for i in 0..plan.exposures.len() {
            let exposure = plan.wire_exposure(i).unwrap();
            let r = call(
                board,
                10 + i as u32,
                Request::AddExposure {
                    index: i as u16,
                    exposure,
                },
            );
            assert!(matches!(
                response(&r, 10 + i as u32),
                Response::ExposureAdded { .. }
            ));
        }
        let r = call(board, 100, Request::CommitPlan);
        assert!(
            matches!(response(&r, 100), Response::PlanCommitted(_)),
            "{r:?}"
        );
        assert_eq!(
            response(&call(board, 101, Request::Arm), 101),
            Response::Armed
        );
        match response(&call(board, 102, Request::Start { delay_ns: 10_000 }), 102) {
            Response::Started { start_tick } => start_tick,
            other => panic!("{other:?}"),
        }
    }

    fn finished(frames: &[BoardFrame]) -> (ScanState, protocol::ScanReport) {
        frames
            .iter()
            .find_map(|f| match f {
                BoardFrame::Event(Event::ScanFinished { state, report }) => Some((*state, *report)),
                _ => None,
            })
            .expect("a ScanFinished event")
    }

    #[test]
    fn runs_the_24_pattern_plan_with_every_feedback_edge_on_time() {
        let plan = examples::multiplexed_24_at_5khz(3);
        let mut board = SimBoard::new(SimBoardConfig::default());
        let start_tick = start(&mut board, &plan);
        board.run_scan();
        let (state, report) = finished(&drain(&mut board));
        assert_eq!(state, ScanState::Done);
        // 3 cycles x (24 projector + 1 camera pulses) x 2 edges, each mirrored.
        assert_eq!(report.expected, 3 * 25 * 2);
        assert_eq!(report.on_time, report.expected, "{report:?}");
        let edges = board.hardware().recorded();
        assert_eq!(edges.len(), 3 * 25 * 2);
        assert!(edges.iter().all(|e| e.tick > start_tick));
        assert_eq!(board.rig_heads(), plan.heads.as_slice());
        // The DMD shows each pattern for the plan's 200 us, less at most the
        // jitter by which the next pattern may come early.
        let jitter_ns = ProjectorModel::Dlpc900.profile().jitter_ns as u64;
        for shown in board.hardware().heads()[0].projector.displayed() {
            let display_ns = shown.end_ns - shown.start_ns;
            assert!(
                display_ns <= 200_000 && display_ns >= 200_000 - 2 * jitter_ns,
                "{shown:?}"
            );
        }
    }

    /// Issue 21: a board with a line each way per device of four heads
    /// runs a four-head plan with every feedback edge on time and every
    /// camera exposing; the STM32G474's 4 lines refuse it, in heads.
    #[test]
    fn four_heads_run_on_a_board_with_eight_lines_and_are_refused_on_four() {
        let plan = examples::all_heads_psp(4, 1);
        let eight_lines = BoardLimits {
            output_channels: 8,
            feedback_channels: 8,
            ..BoardLimits::STM32G474
        };
        let mut board = SimBoard::with_limits(SimBoardConfig::default(), eight_lines);
        start(&mut board, &plan);
        board.run_scan();
        let (state, report) = finished(&drain(&mut board));
        assert_eq!(state, ScanState::Done);
        // Four edges (trigger-out rise/fall, exposure-active rise/fall) per
        // head per exposure.
        assert_eq!(report.expected, 4 * 4 * 16);
        assert_eq!(report.on_time, report.expected, "{report:?}");
        assert_eq!(board.rig_heads().len(), 4);
        for head in board.hardware().heads() {
            assert_eq!(head.camera.exposures().len(), 16);
        }

        let mut two_head_board = SimBoard::new(SimBoardConfig::default());
        call(&mut two_head_board, 1, Request::BeginPlan(plan.header()));
        for i in 0..plan.exposures.len() {
            let exposure = plan.wire_exposure(i).unwrap();
            let index = i as u16;
            call(
                &mut two_head_board,
                10 + i as u32,
                Request::AddExposure { index, exposure },
            );
        }
        let r = call(&mut two_head_board, 100, Request::CommitPlan);
        assert_eq!(
            response(&r, 100),
            Response::Refused(protocol::WireError::Plan(
                protocol::PlanError::TooManyHeadsForBoard {
                    heads: 4,
                    output_channels: 4,
                    feedback_channels: 4,
                    max_heads: 2
                }
            ))
        );
    }

    #[test]
    fn same_seed_same_timeline() {
        let plan = examples::dual_head_psp(1);
        let run = |seed| {
            let mut board = SimBoard::new(SimBoardConfig {
                seed,
                ..SimBoardConfig::default()
            });
            start(&mut board, &plan);
            board.run_scan();
            let h = &board.hardware().heads()[1];
            (h.camera.exposures().to_vec(), board.hardware().now_ticks())
        };
        assert_eq!(run(3), run(3));
        assert_ne!(run(3).0, run(4).0, "jitter depends on the seed");
    }

    #[test]
    fn missed_trigger_is_reported_missing() {
        let faults = FaultPlan {
            missed_triggers: [MissedTrigger {
                camera: 0,
                trigger_index: 1,
            }]
            .into(),
            ..FaultPlan::none()
        };
        let mut board = SimBoard::new(SimBoardConfig { seed: 1, faults });
        start(&mut board, &examples::multiplexed_24_at_5khz(3));
        board.run_scan();
        let frames = drain(&mut board);
        let (state, report) = finished(&frames);
        assert_eq!(state, ScanState::Done);
        assert_eq!(
            report.missing, 2,
            "rise and fall of exposure-active, cycle 1"
        );
        let missing: Vec<u32> = frames
            .iter()
            .filter_map(|f| match f {
                BoardFrame::Event(Event::FeedbackMissing {
                    feedback_channel: 1,
                    cycle,
                    ..
                }) => Some(*cycle),
                _ => None,
            })
            .collect();
        assert_eq!(missing, vec![1, 1]);
    }

    #[test]
    fn corrupted_request_gets_a_link_error_then_the_link_recovers() {
        let faults = FaultPlan {
            to_board: StreamFaults {
                flip_bits: [(3, 2)].into(),
                ..StreamFaults::default()
            },
            ..FaultPlan::none()
        };
        let mut board = SimBoard::new(SimBoardConfig { seed: 0, faults });
        let first = call(&mut board, 1, Request::Ping { nonce: 9 });
        assert!(
            matches!(
                first.as_slice(),
                [BoardFrame::LinkError(WireError::Frame(_))]
            ),
            "{first:?}"
        );
        let second = call(&mut board, 1, Request::Ping { nonce: 9 });
        assert_eq!(response(&second, 1), Response::Pong { nonce: 9 });
    }

    #[test]
    fn vanished_board_says_nothing_more() {
        let faults = FaultPlan {
            vanish_at_tick: Some(1_000_000),
            ..FaultPlan::none()
        };
        let mut board = SimBoard::new(SimBoardConfig { seed: 0, faults });
        start(&mut board, &examples::multiplexed_24_at_5khz(3));
        board.run_scan();
        assert!(board.has_vanished());
        assert_eq!(board.hardware().now_ticks(), 1_000_000);
        let after = drain(&mut board);
        assert!(
            !after
                .iter()
                .any(|f| matches!(f, BoardFrame::Event(Event::ScanFinished { .. }))),
            "{after:?}"
        );
        assert!(call(&mut board, 7, Request::Ping { nonce: 1 }).is_empty());
    }

    #[test]
    fn idle_board_keeps_its_clock_still() {
        let mut board = SimBoard::new(SimBoardConfig::default());
        call(&mut board, 1, Request::Ping { nonce: 0 });
        assert!(!board.step());
        assert_eq!(board.hardware().now_ticks(), 0);
    }
}
