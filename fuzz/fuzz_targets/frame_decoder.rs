//! Any bytes into the frame accumulator, in any chunking: no panic, every
//! frame result is a payload or a typed error, and a good frame sent
//! afterwards always gets through (the decoder resynchronises).
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::limits::MAX_FRAME_BYTES;
use protocol::{decode_payload, encode_frame, FrameAccumulator, HostFrame, Request};

fuzz_target!(|data: &[u8]| {
    let (chunk, bytes) = match data.split_first() {
        Some((c, rest)) => (*c as usize + 1, rest),
        None => (1, data),
    };
    let mut acc = FrameAccumulator::new();
    for piece in bytes.chunks(chunk) {
        acc.feed(piece, |frame| {
            if let Ok(payload) = frame {
                assert!(payload.len() <= MAX_FRAME_BYTES);
                let _ = decode_payload::<HostFrame>(payload);
            }
        });
    }
    let mut buf = [0u8; MAX_FRAME_BYTES];
    let n = encode_frame(
        &HostFrame {
            id: 7,
            request: Request::Ping { nonce: 1 },
        },
        &mut buf,
    )
    .unwrap();
    let mut got = None;
    acc.feed(&[0], |_| {});
    acc.feed(&buf[..n], |frame| {
        got = Some(frame.and_then(decode_payload::<HostFrame>))
    });
    assert_eq!(got.unwrap().unwrap().id, 7);
});
