//! The 64-byte HID reports both DLPC controllers speak (DLPC350: DLPU010
//! §1.4 "USB"; DLPC900: DLPU018 §2.1 "USB"; layout as TI's own
//! `dlpc350_api.h` `hidMessageStruct` and pyCrafter4500 / Pycrafter6500
//! build it):
//!
//! ```text
//! host -> device, one message = a first report + continuation reports
//!   [0]     HID report id 0 (hidapi's first byte; not on the wire)
//!   [1]     flags: bit 7 read (1) / write (0), bit 6 reply wanted,
//!           bit 5 nack (device -> host: the command failed), bits 2:0 destination 0
//!   [2]     sequence byte, echoed by the reply
//!   [3..5]  message length, little-endian: the 2 command bytes + data
//!   [5..7]  command, little-endian (0x1A34 is sent 0x34 0x1A)
//!   [7..65] data; a longer message continues in reports of 64 data bytes
//!           (no header), up to MAX_MESSAGE_BYTES in all
//! device -> host, one report of 64 bytes (no report id on a read)
//!   [0] flags (bit 5 nack) [1] sequence [2..4] length LE [4..] data
//! ```

/// Bytes hidapi writes per report: the report id and 64 bytes.
pub const REPORT_LEN: usize = 65;
/// Bytes of a report read from the device.
pub const REPLY_LEN: usize = 64;
/// Largest message text (command + data): TI's `HID_MESSAGE_MAX_SIZE` in
/// dlpc350_common.h.
pub const MAX_MESSAGE_BYTES: usize = 512;
/// Data bytes the first report carries after the 4-byte header and the
/// 2 command bytes.
pub const FIRST_REPORT_DATA: usize = 64 - 4 - 2;

/// Flag bit: the host reads.
pub const FLAG_READ: u8 = 0x80;
/// Flag bit: the host wants a reply (an ack for a write).
pub const FLAG_REPLY: u8 = 0x40;
/// Flag bit in a reply: the device refused the command.
pub const FLAG_NACK: u8 = 0x20;

/// A command message to send: direction, command and data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Message {
    /// Read (the reply carries data) or write (the reply is an ack).
    pub read: bool,
    /// 16-bit command (CMD2 << 8 | CMD3 in TI's tables).
    pub command: u16,
    /// The data after the command bytes.
    pub data: Vec<u8>,
}

/// Why a message cannot be framed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("command {command:#06x}: {len} data bytes, a message holds at most {max}")]
pub struct MessageTooLong {
    /// The command.
    pub command: u16,
    /// Data bytes asked for.
    pub len: usize,
    /// Data bytes a message holds.
    pub max: usize,
}

impl Message {
    /// A write of `data` to `command`.
    pub fn write(command: u16, data: &[u8]) -> Self {
        Message {
            read: false,
            command,
            data: data.to_vec(),
        }
    }

    /// A read of `command` (with the parameter bytes some reads take).
    pub fn read(command: u16, data: &[u8]) -> Self {
        Message {
            read: true,
            command,
            data: data.to_vec(),
        }
    }

    /// The reports carrying this message with sequence byte `seq`, reply
    /// requested (the driver waits for every ack, so a refused write is
    /// known before the next one).
    pub fn reports(&self, seq: u8) -> Result<Vec<[u8; REPORT_LEN]>, MessageTooLong> {
        let text_len = self.data.len() + 2;
        if text_len > MAX_MESSAGE_BYTES {
            return Err(MessageTooLong {
                command: self.command,
                len: self.data.len(),
                max: MAX_MESSAGE_BYTES - 2,
            });
        }
        let mut first = [0u8; REPORT_LEN];
        first[1] = if self.read { FLAG_READ } else { 0 } | FLAG_REPLY;
        first[2] = seq;
        first[3..5].copy_from_slice(&(text_len as u16).to_le_bytes());
        first[5..7].copy_from_slice(&self.command.to_le_bytes());
        let head = self.data.len().min(FIRST_REPORT_DATA);
        first[7..7 + head].copy_from_slice(&self.data[..head]);
        let mut out = vec![first];
        for chunk in self.data[head..].chunks(64) {
            let mut r = [0u8; REPORT_LEN];
            r[1..1 + chunk.len()].copy_from_slice(chunk);
            out.push(r);
        }
        Ok(out)
    }
}

/// A reply as the device sent it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reply<'a> {
    /// The device refused the command (nack bit).
    pub nack: bool,
    /// The sequence byte it answers.
    pub seq: u8,
    /// Its data (a read's answer; empty or ignored for an ack).
    pub data: &'a [u8],
}

/// A reply that cannot be read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// Fewer bytes than the 4-byte header.
    #[error("reply of {len} bytes, shorter than its 4-byte header")]
    Short {
        /// Bytes received.
        len: usize,
    },
    /// A length field past the report's end.
    #[error("reply claims {claimed} data bytes, the report carries {available}")]
    Length {
        /// The length field.
        claimed: usize,
        /// Bytes after the header.
        available: usize,
    },
    /// The reply answers another message.
    #[error("reply to sequence {got}, expected {expected}")]
    Sequence {
        /// Sequence byte sent.
        expected: u8,
        /// Sequence byte received.
        got: u8,
    },
}

/// Parses one report read from the device (with or without hidapi's
/// leading report id: pass the 64 bytes after it). Device replies are input
/// from outside: every length is checked, nothing panics (fuzzed:
/// fuzz/fuzz_targets/dlpc_reply.rs).
///
/// ```
/// use slscan::rig::dlpc::report::{parse_reply, Reply};
/// let r = [0x40, 7, 2, 0, 0xAB, 0xCD, 0, 0];
/// assert_eq!(parse_reply(&r, Some(7)).unwrap(), Reply { nack: false, seq: 7, data: &[0xAB, 0xCD] });
/// ```
pub fn parse_reply(report: &[u8], expected_seq: Option<u8>) -> Result<Reply<'_>, ReplyError> {
    if report.len() < 4 {
        return Err(ReplyError::Short { len: report.len() });
    }
    let (flags, seq) = (report[0], report[1]);
    let claimed = u16::from_le_bytes([report[2], report[3]]) as usize;
    let available = report.len() - 4;
    if claimed > available {
        return Err(ReplyError::Length { claimed, available });
    }
    if let Some(expected) = expected_seq {
        if seq != expected {
            return Err(ReplyError::Sequence { expected, got: seq });
        }
    }
    Ok(Reply {
        nack: flags & FLAG_NACK != 0,
        seq,
        data: &report[4..4 + claimed],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_write_fits_one_report_with_the_command_little_endian() {
        let r = Message::write(0x1A24, &[2]).reports(5).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(&r[0][..8], &[0, 0x40, 5, 3, 0, 0x24, 0x1A, 2]);
        assert!(r[0][8..].iter().all(|&b| b == 0));
        let read = Message::read(0x0205, &[]).reports(1).unwrap();
        assert_eq!(&read[0][..7], &[0, 0xC0, 1, 2, 0, 0x05, 0x02]);
    }

    #[test]
    fn a_long_message_continues_in_64_byte_reports() {
        let data: Vec<u8> = (0..200u32).map(|i| i as u8).collect();
        let r = Message::write(0x1A2B, &data).reports(0).unwrap();
        // 58 bytes in the first report, then 64 + 64 + 14.
        assert_eq!(r.len(), 4);
        assert_eq!(u16::from_le_bytes([r[0][3], r[0][4]]), 202);
        assert_eq!(r[0][7 + 57], 57);
        assert_eq!(r[1][1], 58);
        assert_eq!(r[3][1 + 13], 199);
        assert!(Message::write(1, &[0; 511]).reports(0).is_err());
        assert_eq!(Message::write(1, &[0; 510]).reports(0).unwrap().len(), 9);
    }

    #[test]
    fn replies_are_checked_not_trusted() {
        assert_eq!(
            parse_reply(&[0x40], None),
            Err(ReplyError::Short { len: 1 })
        );
        assert_eq!(
            parse_reply(&[0x40, 0, 9, 0, 1], None),
            Err(ReplyError::Length {
                claimed: 9,
                available: 1
            })
        );
        assert_eq!(
            parse_reply(&[0x60, 3, 0, 0], Some(4)),
            Err(ReplyError::Sequence {
                expected: 4,
                got: 3
            })
        );
        assert!(parse_reply(&[0x60, 3, 0, 0], Some(3)).unwrap().nack);
    }
}
