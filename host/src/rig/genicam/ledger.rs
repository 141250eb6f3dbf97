//! What a camera's stream delivered for one plan, checked against what the
//! board triggered: every trigger gave one complete frame, in order, or the
//! scan fails naming the frame. Pure: the Aravis layer feeds it arrivals.
//!
//! GigE Vision 1.x block ids are 16-bit, run 1..=65535 and skip 0 on wrap;
//! USB3 Vision and GigE Vision 2 extended ids are 64-bit from 0. A gap in
//! the ids is a trigger whose frame never came (the camera dropped it, or
//! the stream lost its leader).

/// One buffer as the stream gave it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Arrival {
    /// The GenICam block (frame) id; 0 when the stream never saw the
    /// frame's leader.
    pub frame_id: u64,
    /// The camera's time stamp, ns (the device clock).
    pub device_ns: u64,
    /// The host's time stamp when the frame completed, ns.
    pub host_ns: u64,
    /// Whether the buffer came whole, or how it failed.
    pub status: ArrivalStatus,
}

/// A buffer's status, as far as a scan cares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArrivalStatus {
    /// Every packet arrived (resent ones included).
    Complete,
    /// Packets were lost and not recovered by resends.
    MissingPackets,
    /// The stream gave up on the frame (frame retention elapsed).
    TimedOut,
    /// The buffer was too small for the frame.
    SizeMismatch,
    /// Any other failure the stream reports (its name).
    Other(&'static str),
}

/// Why a head's frames cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LedgerError {
    /// A frame came broken: the scan would silently miss a pattern.
    #[error("frame {index} (block id {frame_id}) came incomplete: {status:?}")]
    Incomplete {
        /// Position in trigger order (0-based).
        index: usize,
        /// Its block id.
        frame_id: u64,
        /// How it failed.
        status: ArrivalStatus,
    },
    /// Block ids jumped: triggers with no frame.
    #[error("{missed} trigger(s) gave no frame: block ids jump from {before} to {after} at frame {index}")]
    Gap {
        /// Position of the frame after the gap.
        index: usize,
        /// Id before the gap.
        before: u64,
        /// Id after the gap.
        after: u64,
        /// Frames missing in between.
        missed: u64,
    },
    /// The same block id twice in a row (a resent whole frame, or a
    /// camera that does not count).
    #[error("frame {index} repeats block id {frame_id}")]
    Repeated {
        /// Position of the repeat.
        index: usize,
        /// The id.
        frame_id: u64,
    },
    /// Fewer frames than triggers by the time-out.
    #[error("{got} frame(s) for {expected} trigger(s)")]
    TooFew {
        /// Triggers sent.
        expected: usize,
        /// Frames received.
        got: usize,
    },
    /// More frames than triggers (a double trigger, or a free-running camera).
    #[error("{got} frame(s) for {expected} trigger(s)")]
    TooMany {
        /// Triggers sent.
        expected: usize,
        /// Frames received.
        got: usize,
    },
}

/// Ids from `before` to `after` in the camera's counting: 1 for
/// consecutive frames. Both under 2^16 counts on the GigE Vision 1.x wheel
/// (65535 is followed by 1); otherwise plain 64-bit counting.
pub fn id_step(before: u64, after: u64) -> u64 {
    const WHEEL: u64 = 65_535;
    if before <= WHEEL && after <= WHEEL && after <= before {
        // Wrapped: 1..=65535 has 65535 values (0 is never used after a wrap).
        (after + WHEEL - before) % WHEEL
    } else {
        after.wrapping_sub(before)
    }
}

/// Checks `arrivals` (in the stream's order) against `expected` triggers:
/// `Ok` only when there are exactly that many, all complete, with
/// consecutive ids.
pub fn check_arrivals(arrivals: &[Arrival], expected: usize) -> Result<(), LedgerError> {
    if let Some((index, a)) = arrivals
        .iter()
        .enumerate()
        .find(|(_, a)| a.status != ArrivalStatus::Complete)
    {
        return Err(LedgerError::Incomplete {
            index,
            frame_id: a.frame_id,
            status: a.status,
        });
    }
    for (index, pair) in arrivals.windows(2).enumerate() {
        let step = id_step(pair[0].frame_id, pair[1].frame_id);
        if step == 0 {
            return Err(LedgerError::Repeated {
                index: index + 1,
                frame_id: pair[1].frame_id,
            });
        }
        if step != 1 {
            return Err(LedgerError::Gap {
                index: index + 1,
                before: pair[0].frame_id,
                after: pair[1].frame_id,
                missed: step - 1,
            });
        }
    }
    match arrivals.len() {
        n if n < expected => Err(LedgerError::TooFew { expected, got: n }),
        n if n > expected => Err(LedgerError::TooMany { expected, got: n }),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn complete(ids: &[u64]) -> Vec<Arrival> {
        ids.iter()
            .map(|&frame_id| Arrival {
                frame_id,
                device_ns: frame_id * 1000,
                host_ns: frame_id * 1000,
                status: ArrivalStatus::Complete,
            })
            .collect()
    }

    #[test]
    fn consecutive_ids_across_the_16_bit_wrap_pass() {
        assert_eq!(check_arrivals(&complete(&[65534, 65535, 1, 2]), 4), Ok(()));
        assert_eq!(id_step(65535, 1), 1);
        assert_eq!(id_step(7, 8), 1);
        assert_eq!(id_step(65535, 65536), 1); // 64-bit ids do not wrap there
    }

    #[test]
    fn a_gap_names_where_and_how_many() {
        let err = check_arrivals(&complete(&[10, 11, 14, 15]), 6).unwrap_err();
        assert_eq!(
            err,
            LedgerError::Gap {
                index: 2,
                before: 11,
                after: 14,
                missed: 2
            }
        );
        let err = check_arrivals(&complete(&[65534, 2]), 4).unwrap_err();
        assert!(matches!(err, LedgerError::Gap { missed: 2, .. }));
    }

    #[test]
    fn a_repeated_id_is_not_a_gap_of_2_to_the_64() {
        assert_eq!(
            check_arrivals(&complete(&[4, 4]), 2),
            Err(LedgerError::Repeated {
                index: 1,
                frame_id: 4
            })
        );
    }

    #[test]
    fn an_incomplete_frame_is_named_before_counts() {
        let mut arrivals = complete(&[1, 2, 3]);
        arrivals[1].status = ArrivalStatus::MissingPackets;
        assert_eq!(
            check_arrivals(&arrivals, 5),
            Err(LedgerError::Incomplete {
                index: 1,
                frame_id: 2,
                status: ArrivalStatus::MissingPackets
            })
        );
    }

    #[test]
    fn counts_must_match_the_triggers() {
        assert_eq!(
            check_arrivals(&complete(&[1, 2]), 3),
            Err(LedgerError::TooFew {
                expected: 3,
                got: 2
            })
        );
        assert_eq!(
            check_arrivals(&complete(&[1, 2, 3]), 2),
            Err(LedgerError::TooMany {
                expected: 2,
                got: 3
            })
        );
        assert_eq!(
            check_arrivals(&[], 1),
            Err(LedgerError::TooFew {
                expected: 1,
                got: 0
            })
        );
    }
}
