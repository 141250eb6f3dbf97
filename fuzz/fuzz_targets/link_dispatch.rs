//! The board's whole request path, as the STM32 and hil-sim run it:
//! `board_core::Link::receive` / `poll` on bytes the fuzzer chooses. Input is
//! a sequence of segments `[mode, len, bytes..]`:
//! - mode 0: raw bytes (garbage, partial frames);
//! - mode 1: the bytes as a *well-framed* payload (valid CRC + COBS), so the
//!   fuzzer reaches postcard decoding and the dispatcher directly;
//! - mode 2: a random valid plan upload + Arm + Start seeded by the bytes;
//! - mode 3: advance the fake timer by the bytes (as ticks) and poll, with
//!   feedback captures derived from the bytes.
//! Checks: no panic; every byte the board sends decodes as a `BoardFrame`;
//! every well-framed request gets exactly one answer.
#![no_main]

use board_core::{Capture, EdgeTable, Link, TriggerHardware};
use libfuzzer_sys::fuzz_target;
use protocol::framing::CRC32;
use protocol::limits::{MAX_FRAME_BYTES, MAX_PAYLOAD_BYTES};
use protocol::plan::random::{random_kind, random_plan, SplitMix64};
use protocol::{
    decode_payload, encode_frame, BoardFrame, BoardLimits, DeviceInfo, FirmwareVersion,
    FrameAccumulator, HardwareFault, HostFrame, Level, Request, ResetCause, PROTOCOL_VERSION,
};

#[derive(Default)]
struct FuzzHardware {
    now: u64,
    captures: Vec<Capture>,
}

impl TriggerHardware for FuzzHardware {
    fn load(&mut self, table: &EdgeTable) -> Result<(), HardwareFault> {
        if table.edges().len() > 1_000 {
            return Err(HardwareFault::TableTooLarge {
                edges: table.edges().len() as u16,
                capacity: 1_000,
            });
        }
        Ok(())
    }
    fn start(&mut self, start_tick: u64, _repeat_count: u32) -> Result<(), HardwareFault> {
        if start_tick <= self.now {
            return Err(HardwareFault::StartInPast {
                start_tick,
                now_tick: self.now,
            });
        }
        Ok(())
    }
    fn stop(&mut self) {}
    fn now_ticks(&self) -> u64 {
        self.now
    }
    fn pop_capture(&mut self) -> Option<Capture> {
        self.captures.pop()
    }
    fn fault(&self) -> Option<HardwareFault> {
        None
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
        board_id: 1,
        limits: BoardLimits::STM32G474,
        reset_cause: ResetCause::Simulated,
    }
}

/// A frame around an arbitrary payload (valid CRC and COBS).
fn frame_payload(payload: &[u8], out: &mut Vec<u8>) {
    let payload = &payload[..payload.len().min(MAX_PAYLOAD_BYTES)];
    let mut raw = payload.to_vec();
    raw.extend_from_slice(&CRC32.checksum(payload).to_le_bytes());
    let mut enc = vec![0u8; raw.len() + raw.len() / 254 + 2];
    let n = cobs_encode(&raw, &mut enc);
    out.extend_from_slice(&enc[..n]);
    out.push(0);
}

/// COBS encoding (kept here so the target checks the decoder against an
/// independent encoder).
fn cobs_encode(src: &[u8], dst: &mut [u8]) -> usize {
    let (mut code_at, mut out, mut code) = (0usize, 1usize, 1u8);
    for &b in src {
        if b == 0 {
            dst[code_at] = code;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            dst[out] = b;
            out += 1;
            code += 1;
            if code == 0xFF {
                dst[code_at] = code;
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    dst[code_at] = code;
    out
}

fn encode(frame: &HostFrame, out: &mut Vec<u8>) {
    let mut buf = [0u8; MAX_FRAME_BYTES];
    let n = encode_frame(frame, &mut buf).expect("every request fits a frame");
    out.extend_from_slice(&buf[..n]);
}

fn valid_upload(seed: &[u8], out: &mut Vec<u8>) {
    let mut s = [0u8; 8];
    s[..seed.len().min(8)].copy_from_slice(&seed[..seed.len().min(8)]);
    let mut bits = SplitMix64(u64::from_le_bytes(s));
    let plan = random_plan(random_kind(&mut bits), &mut bits);
    encode(
        &HostFrame {
            id: 1,
            request: Request::BeginPlan(plan.header()),
        },
        out,
    );
    for i in 0..plan.exposures.len() {
        let exposure = plan.wire_exposure(i).expect("in range");
        encode(
            &HostFrame {
                id: 2 + i as u32,
                request: Request::AddExposure {
                    index: i as u16,
                    exposure,
                },
            },
            out,
        );
    }
    for (id, request) in [
        (100, Request::CommitPlan),
        (101, Request::Arm),
        (102, Request::Start { delay_ns: 0 }),
    ] {
        encode(&HostFrame { id, request }, out);
    }
}

fuzz_target!(|data: &[u8]| {
    let mut link = Link::new(info());
    let mut hw = FuzzHardware::default();
    let mut host = FrameAccumulator::new();
    let mut check = |bytes: &[u8]| {
        host.feed(bytes, |f| {
            let frame = f.expect("the board sends whole frames");
            decode_payload::<BoardFrame>(frame).expect("the board sends valid messages");
        });
    };
    let mut rest = data;
    while let [mode, len, tail @ ..] = rest {
        let take = (*len as usize).min(tail.len());
        let (segment, next) = tail.split_at(take);
        rest = next;
        let mut bytes = Vec::new();
        match mode % 4 {
            0 => bytes.extend_from_slice(segment),
            1 => frame_payload(segment, &mut bytes),
            2 => valid_upload(segment, &mut bytes),
            _ => {
                for (i, pair) in segment.chunks(2).enumerate() {
                    let tick = hw.now + pair.iter().map(|&b| b as u64).product::<u64>() * 97;
                    let level = if i % 2 == 0 { Level::High } else { Level::Low };
                    hw.captures.push(Capture {
                        feedback_channel: pair[0] % 5,
                        level,
                        tick,
                    });
                }
                let step: u64 = segment.iter().map(|&b| b as u64).sum::<u64>() << 10;
                hw.now += step;
                let mut sent = Vec::new();
                link.poll(&mut hw, &mut |f: &[u8]| sent.extend_from_slice(f));
                check(&sent);
                continue;
            }
        }
        let mut sent = Vec::new();
        link.receive(&bytes, &mut hw, &mut |f: &[u8]| sent.extend_from_slice(f));
        assert!(sent.len() <= 64 * MAX_FRAME_BYTES * (bytes.len() + 1));
        check(&sent);
        hw.now += 1_000;
    }
});
