//! COBS frames with a CRC-32 trailer over a postcard payload.
//!
//! ```text
//! message --postcard--> payload ++ crc32_le(payload) --COBS--> bytes ++ 0x00
//! ```
//!
//! [`FrameAccumulator`] takes bytes as they arrive (any chunking), returns
//! each payload whose CRC checks, and reports garbage as a [`FrameError`]
//! instead of panicking: it resynchronises at the next `0x00`.
//!
//! ```
//! use protocol::{decode_payload, encode_frame, FrameAccumulator, HostFrame, Request};
//! let mut wire = [0u8; 64];
//! let n = encode_frame(&HostFrame { id: 3, request: Request::Ping { nonce: 9 } }, &mut wire).unwrap();
//! assert_eq!(wire[n - 1], 0); // the delimiter
//! let mut acc = FrameAccumulator::new();
//! let mut got = Vec::new();
//! // Garbage first, then the frame in two pieces.
//! acc.feed(&[0x17, 0x00], |f| got.push(f.and_then(decode_payload::<HostFrame>)));
//! acc.feed(&wire[..2], |f| got.push(f.and_then(decode_payload::<HostFrame>)));
//! acc.feed(&wire[2..n], |f| got.push(f.and_then(decode_payload::<HostFrame>)));
//! assert!(got[0].is_err());
//! assert_eq!(got[1], Ok(HostFrame { id: 3, request: Request::Ping { nonce: 9 } }));
//! ```

use serde::{de::DeserializeOwned, Serialize};

use crate::error::FrameError;
use crate::limits::{CRC_BYTES, MAX_FRAME_BYTES, MAX_PAYLOAD_BYTES};

/// CRC-32 (ISO-HDLC, the Ethernet/zlib polynomial) over the payload.
pub const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Encodes `message` as one frame into `out`; returns the frame's length,
/// terminating `0x00` included.
pub fn encode_frame<T: Serialize>(message: &T, out: &mut [u8]) -> Result<usize, FrameError> {
    let mut raw = [0u8; MAX_PAYLOAD_BYTES + CRC_BYTES];
    let payload_len = postcard::to_slice(message, &mut raw[..MAX_PAYLOAD_BYTES])
        .map_err(|_| FrameError::PayloadTooLarge)?
        .len();
    let crc = CRC32.checksum(&raw[..payload_len]);
    raw[payload_len..payload_len + CRC_BYTES].copy_from_slice(&crc.to_le_bytes());
    let raw_len = payload_len + CRC_BYTES;
    let needed = cobs::max_encoding_length(raw_len) + 1;
    if out.len() < needed {
        return Err(FrameError::OutputTooSmall {
            needed: needed as u16,
        });
    }
    let n = cobs::encode(&raw[..raw_len], out);
    out[n] = 0;
    Ok(n + 1)
}

/// Decodes a payload returned by [`FrameAccumulator`] as a `T`.
pub fn decode_payload<T: DeserializeOwned>(payload: &[u8]) -> Result<T, FrameError> {
    postcard::from_bytes(payload).map_err(|_| FrameError::Deserialize)
}

/// Collects bytes into frames.
#[derive(Debug, Clone)]
pub struct FrameAccumulator {
    buf: [u8; MAX_FRAME_BYTES],
    len: usize,
    overflowed: bool,
}

impl Default for FrameAccumulator {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameAccumulator {
    /// An empty accumulator.
    pub const fn new() -> Self {
        FrameAccumulator {
            buf: [0; MAX_FRAME_BYTES],
            len: 0,
            overflowed: false,
        }
    }

    /// Takes one byte; at a delimiter returns the frame's payload (CRC
    /// removed) or why it was bad. Empty frames (two delimiters in a row,
    /// which a sender may use to resynchronise) are skipped.
    pub fn push(&mut self, byte: u8) -> Option<Result<&[u8], FrameError>> {
        if byte != 0 {
            if self.len < MAX_FRAME_BYTES {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflowed = true;
            }
            return None;
        }
        let len = core::mem::take(&mut self.len);
        if core::mem::take(&mut self.overflowed) {
            return Some(Err(FrameError::Oversized {
                limit: MAX_FRAME_BYTES as u16,
            }));
        }
        if len == 0 {
            return None;
        }
        Some(check_frame(&mut self.buf[..len]))
    }

    /// Feeds `bytes`, calling `on_frame` for every frame they complete.
    pub fn feed(&mut self, bytes: &[u8], mut on_frame: impl FnMut(Result<&[u8], FrameError>)) {
        for &byte in bytes {
            if let Some(result) = self.push(byte) {
                on_frame(result);
            }
        }
    }

    /// Bytes held of an unfinished frame.
    pub fn pending(&self) -> usize {
        self.len
    }
}

/// COBS-decodes `frame` in place and checks its CRC; returns the payload.
fn check_frame(frame: &mut [u8]) -> Result<&[u8], FrameError> {
    let n = cobs::decode_in_place(frame).map_err(|_| FrameError::Cobs)?;
    if n < CRC_BYTES {
        return Err(FrameError::TooShort { len: n as u16 });
    }
    let (payload, trailer) = frame[..n].split_at(n - CRC_BYTES);
    let mut crc_bytes = [0u8; CRC_BYTES];
    crc_bytes.copy_from_slice(trailer);
    let received = u32::from_le_bytes(crc_bytes);
    let computed = CRC32.checksum(payload);
    if received != computed {
        return Err(FrameError::CrcMismatch { received, computed });
    }
    Ok(payload)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::{HostFrame, Request};

    fn frame(id: u32) -> ([u8; MAX_FRAME_BYTES], usize) {
        let mut out = [0u8; MAX_FRAME_BYTES];
        let n = encode_frame(
            &HostFrame {
                id,
                request: Request::Ping { nonce: 7 },
            },
            &mut out,
        )
        .unwrap();
        (out, n)
    }

    fn collect(
        acc: &mut FrameAccumulator,
        bytes: &[u8],
    ) -> heapless::Vec<Result<HostFrame, FrameError>, 8> {
        let mut got = heapless::Vec::new();
        acc.feed(bytes, |r| {
            let _ = got.push(r.and_then(decode_payload::<HostFrame>));
        });
        got
    }

    #[test]
    fn roundtrip_byte_by_byte() {
        let (buf, n) = frame(42);
        let mut acc = FrameAccumulator::new();
        let mut got = heapless::Vec::<_, 2>::new();
        for &b in &buf[..n] {
            got.extend(collect(&mut acc, &[b]));
        }
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].as_ref().unwrap().id, 42);
    }

    #[test]
    fn flipped_bit_is_a_crc_error_then_link_recovers() {
        let (mut buf, n) = frame(1);
        buf[2] ^= 0x10;
        let (good, m) = frame(2);
        let mut acc = FrameAccumulator::new();
        let first = collect(&mut acc, &buf[..n]);
        assert!(matches!(
            first[0],
            Err(FrameError::CrcMismatch { .. }) | Err(FrameError::Cobs)
        ));
        let second = collect(&mut acc, &good[..m]);
        assert_eq!(second[0].as_ref().unwrap().id, 2);
    }

    #[test]
    fn garbage_without_delimiter_is_oversized_then_recovers() {
        let mut acc = FrameAccumulator::new();
        let garbage = [0x55u8; MAX_FRAME_BYTES + 10];
        assert!(collect(&mut acc, &garbage).is_empty());
        let got = collect(&mut acc, &[0]);
        assert_eq!(
            got[0],
            Err(FrameError::Oversized {
                limit: MAX_FRAME_BYTES as u16
            })
        );
        let (good, m) = frame(3);
        assert_eq!(collect(&mut acc, &good[..m])[0].as_ref().unwrap().id, 3);
    }

    #[test]
    fn truncated_frame_is_an_error() {
        let (buf, n) = frame(4);
        let mut acc = FrameAccumulator::new();
        let mut cut = [0u8; MAX_FRAME_BYTES];
        cut[..3].copy_from_slice(&buf[..3]);
        let got = collect(&mut acc, &cut[..4]);
        assert!(got[0].is_err());
        assert!(n > 4);
    }

    #[test]
    fn too_large_message_is_refused() {
        let big = [7u8; MAX_PAYLOAD_BYTES + 1];
        let mut out = [0u8; MAX_FRAME_BYTES];
        // A byte array serialises as a tuple of its bytes: one byte each.
        assert_eq!(
            encode_frame(&big_array(&big), &mut out),
            Err(FrameError::PayloadTooLarge)
        );
    }

    fn big_array(bytes: &[u8]) -> heapless::Vec<u8, 600> {
        heapless::Vec::from_slice(bytes).unwrap()
    }
}
