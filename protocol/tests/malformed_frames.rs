//! Garbage, flipped bits and cut frames: the accumulator reports an error,
//! never panics, and the next good frame gets through.

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use protocol::limits::MAX_FRAME_BYTES;
use protocol::{decode_payload, encode_frame, FrameAccumulator, FrameError, HostFrame, Request};

fn good(id: u32) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_BYTES];
    let n = encode_frame(
        &HostFrame {
            id,
            request: Request::Ping { nonce: id ^ 0xA5A5 },
        },
        &mut buf,
    )
    .unwrap();
    buf[..n].to_vec()
}

/// Every frame result the bytes produce, decoded as host frames.
fn results(acc: &mut FrameAccumulator, bytes: &[u8]) -> Vec<Result<HostFrame, FrameError>> {
    let mut out = Vec::new();
    acc.feed(bytes, |frame| {
        out.push(frame.and_then(decode_payload::<HostFrame>))
    });
    out
}

/// After anything, a delimiter and a good frame decode to that frame.
fn recovers(acc: &mut FrameAccumulator) -> Result<(), TestCaseError> {
    let _ = results(acc, &[0]);
    let got = results(acc, &good(99));
    prop_assert_eq!(got.len(), 1);
    prop_assert_eq!(got[0].as_ref().map(|f| f.id), Ok(99));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    #[test]
    fn garbage_never_panics_and_the_link_recovers(bytes in prop::collection::vec(any::<u8>(), 0..2_000)) {
        let mut acc = FrameAccumulator::new();
        let _ = results(&mut acc, &bytes);
        recovers(&mut acc)?;
    }

    #[test]
    fn a_flipped_bit_is_an_error(id in any::<u32>(), bit in any::<prop::sample::Index>()) {
        let mut frame = good(id);
        let body = frame.len() - 1; // keep the delimiter: flips inside the frame
        let at = bit.index(body * 8);
        frame[at / 8] ^= 1 << (at % 8);
        let mut acc = FrameAccumulator::new();
        let got = results(&mut acc, &frame);
        // A flip may create a 0x00 and split the frame: every piece is an error.
        prop_assert!(!got.is_empty());
        prop_assert!(got.iter().all(|r| r.is_err()), "{:?}", got);
        recovers(&mut acc)?;
    }

    #[test]
    fn a_truncated_frame_is_an_error(id in any::<u32>(), cut in any::<prop::sample::Index>()) {
        let frame = good(id);
        let keep = 1 + cut.index(frame.len() - 2); // at least one byte, never the delimiter
        let mut truncated = frame[..keep].to_vec();
        truncated.push(0);
        let mut acc = FrameAccumulator::new();
        let got = results(&mut acc, &truncated);
        prop_assert_eq!(got.len(), 1);
        prop_assert!(got[0].is_err());
        recovers(&mut acc)?;
    }
}

#[test]
fn a_frame_longer_than_the_limit_is_oversized() {
    let mut acc = FrameAccumulator::new();
    let mut bytes = vec![1u8; MAX_FRAME_BYTES + 1];
    bytes.push(0);
    assert_eq!(
        results(&mut acc, &bytes),
        vec![Err(FrameError::Oversized {
            limit: MAX_FRAME_BYTES as u16
        })]
    );
}
