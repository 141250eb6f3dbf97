//! The simulated rig follows the plan: the board reads the plan upload as
//! its dispatcher does and, once the dispatcher has committed it, builds the
//! heads it names, each DMD showing its patterns for the plan's `display_ns`
//! (as a host programs a real DMD's pattern table).

use board_core::EdgeTable;
use protocol::{
    decode_payload, BoardFrame, BoardLimits, CameraModel, FrameAccumulator, HeadConfig, HostFrame,
    ProjectorModel, Request, RequestId, Response, ScanPlan,
};

use super::SimBoardConfig;
use crate::sim_hardware::{camera_config, projector_config, SimHead};

/// Wiring of an absent head: channels no table uses, so it never sees an edge.
pub const ABSENT_HEAD: HeadConfig = HeadConfig {
    projector: ProjectorModel::Dlpc350,
    camera: CameraModel::Mono6Mp,
    projector_trigger_channel: u8::MAX,
    camera_trigger_channel: u8::MAX,
    projector_feedback_channel: u8::MAX,
    camera_feedback_channel: u8::MAX,
};

/// Reads the plan upload out of the host's bytes by the dispatcher's rules:
/// a repeated id (not `Hello`) is a retry the board answers from its cache,
/// and exposures must come in order.
#[derive(Debug, Default)]
pub struct UploadReader {
    frames: FrameAccumulator,
    last_request_id: Option<RequestId>,
    plan: Option<ScanPlan>,
}

impl UploadReader {
    /// Follows `bytes`, which the board's link is about to read.
    pub fn read(&mut self, bytes: &[u8]) {
        let mut requests = Vec::new();
        self.frames.feed(bytes, |frame| {
            if let Ok(host_frame) = frame.and_then(decode_payload::<HostFrame>) {
                requests.push(host_frame);
            }
        });
        for HostFrame { id, request } in requests {
            let retry =
                self.last_request_id == Some(id) && !matches!(request, Request::Hello { .. });
            self.last_request_id = Some(id);
            match request {
                _ if retry => {}
                Request::BeginPlan(header) => self.plan = Some(ScanPlan::from_header(&header)),
                Request::AddExposure { index, exposure } => {
                    if let Some(plan) = self.plan.as_mut() {
                        if index as usize == plan.exposures.len() {
                            // A capacity refusal here is the board's too.
                            let _ = plan.push_wire_exposure(&exposure);
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// The plan read so far, taken (a commit consumes the upload).
    pub fn take_plan(&mut self) -> Option<ScanPlan> {
        self.plan.take()
    }
}

/// Whether `frame` (one encoded board frame) is a `PlanCommitted` answer.
pub fn answers_commit(frame: &[u8]) -> bool {
    let mut acc = FrameAccumulator::new();
    let mut committed = false;
    acc.feed(frame, |f| {
        committed |= matches!(
            f.and_then(decode_payload::<BoardFrame>),
            Ok(BoardFrame::Response {
                response: Response::PlanCommitted(_),
                ..
            })
        );
    });
    committed
}

/// The simulated heads for `plan` (absent ones padded to `MAX_HEADS`), from
/// their models' profiles, with the configured device faults and seeds;
/// `limits` are the simulated board's, which validated the plan.
/// The plan as read must compile to `committed`, the dispatcher's table; if
/// it ever did not, the heads still follow the plan's header but the DMDs
/// keep their profile's display time.
pub fn build_heads(
    plan: &ScanPlan,
    committed: &EdgeTable,
    config: &SimBoardConfig,
    limits: &BoardLimits,
) -> Vec<SimHead> {
    let same_table = plan
        .clone()
        .validate(limits)
        .ok()
        .and_then(|valid| EdgeTable::compile(&valid).ok())
        .is_some_and(|table| table == *committed);
    if !same_table {
        tracing::warn!("simulated rig: the plan read differs from the one committed");
    }
    (0..protocol::limits::MAX_HEADS)
        .map(|index| {
            let wiring = plan.heads.get(index).copied().unwrap_or(ABSENT_HEAD);
            let mut camera = camera_config(wiring.camera);
            camera.missed_triggers = config.faults.missed_by_camera(index as u8);
            let seed = config
                .seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(index as u64);
            let mut projector = projector_config(wiring.projector);
            projector.trigger_delay.latency_ns += config
                .faults
                .projector_lag_ns
                .get(&(index as u8))
                .copied()
                .unwrap_or(0);
            let mut head = SimHead::new(wiring, projector, camera, seed);
            if same_table {
                head.projector
                    .set_display_sequence(display_sequence_ns(plan, index));
            }
            head
        })
        .collect()
}

/// How long head `head`'s DMD shows each pattern, in the order its triggers
/// come within one cycle.
pub fn display_sequence_ns(plan: &ScanPlan, head: usize) -> Vec<u64> {
    plan.exposures()
        .filter(|e| e.entry.heads.contains(head))
        .flat_map(|e| e.slots.iter().map(|slot| slot.display_ns as u64))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::limits::MAX_FRAME_BYTES;
    use protocol::plan::examples;
    use protocol::{encode_frame, HeadSet, PatternSlot};

    fn bytes(id: RequestId, request: Request) -> Vec<u8> {
        let mut buf = [0u8; MAX_FRAME_BYTES];
        let n = encode_frame(&HostFrame { id, request }, &mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn reads_the_upload_ignoring_retries_and_out_of_order_exposures() {
        let plan = examples::dual_head_psp(1);
        let mut reader = UploadReader::default();
        reader.read(&bytes(1, Request::BeginPlan(plan.header())));
        for i in 0..plan.exposures.len() {
            let add = Request::AddExposure {
                index: i as u16,
                exposure: plan.wire_exposure(i).unwrap(),
            };
            let frame = bytes(2 + i as u32, add);
            reader.read(&frame);
            reader.read(&frame); // a retry: same id
        }
        // Out of sequence: refused by the board, ignored here.
        let stray = Request::AddExposure {
            index: 99,
            exposure: plan.wire_exposure(0).unwrap(),
        };
        reader.read(&bytes(500, stray));
        assert_eq!(reader.take_plan(), Some(plan));
        assert_eq!(reader.take_plan(), None);
    }

    #[test]
    fn display_sequence_lists_each_heads_slots_in_order() {
        let mut plan = ScanPlan::new(
            &[examples::head(
                0,
                ProjectorModel::Dlpc900,
                CameraModel::Colour208Hz,
            )],
            1,
            10_000_000,
            500,
        )
        .unwrap();
        let slot = |pattern_index, display_ns| PatternSlot {
            pattern_index,
            offset_ns: 0,
            display_ns,
        };
        plan.push_exposure(HeadSet::A, 0, 1, &[slot(0, 100), slot(1, 200)])
            .unwrap();
        plan.push_exposure(HeadSet::B, 0, 1, &[slot(2, 300)])
            .unwrap();
        plan.push_exposure(HeadSet::BOTH, 0, 1, &[slot(3, 400)])
            .unwrap();
        assert_eq!(display_sequence_ns(&plan, 0), vec![100, 200, 400]);
        assert_eq!(display_sequence_ns(&plan, 1), vec![300, 400]);
    }
}
