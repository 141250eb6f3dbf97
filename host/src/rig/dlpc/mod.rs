//! DMD controllers driven over USB HID: TI's DLPC350 (LightCrafter 4500)
//! and DLPC900 (LightCrafter 6500 / 9000) behind [`Projector`].
//!
//! ```text
//! patterns --packing::pack--> 24-bit images --dlpc350 / dlpc900 builders--> Messages
//!          --report::Message::reports--> 65-byte reports --HidLink--> controller
//!          <--report::parse_reply-- one 64-byte ack or answer per message
//! ```
//!
//! A load checks the set against the controller's
//! [`protocol::ControllerLimits`] first (bit depth's minimum exposure, LUT
//! length, image memory, DMD size), so a set the controller would refuse
//! is a typed error before a byte is sent. It then stops the sequence,
//! uploads images and LUT, validates and starts in external-trigger mode
//! (TRIG_IN_1 rising: the sync board steps it). Until that start succeeds
//! the head counts as empty: a failed or interrupted upload never leaves a
//! half-loaded set claimed as loaded.
//!
//! The link is the small [`HidLink`] trait: hil-sim's byte-level
//! controller (`crate::sim::dlpc`) or, with the `hid` cargo feature, a real
//! device through hidapi (module `hid`).

pub mod dlpc350;
pub mod dlpc900;
#[cfg(feature = "hid")]
pub mod hid;
pub mod packing;
pub mod report;

use protocol::plan::controller::LoadedSet;
use protocol::{ControllerLimitError, ControllerLimits, ProjectorModel, ScanPlan};

use self::report::{parse_reply, Message, MessageTooLong, ReplyError, REPLY_LEN, REPORT_LEN};
use super::{check_sequence, Led, Projector, RigError, WHITE};
use crate::raster::Raster;

/// USB vendor id of both controllers (TI).
pub const TI_VENDOR_ID: u16 = 0x0451;
/// USB product id of the DLPC350 (TI's dlpc350_usb.h `MY_PID`).
pub const DLPC350_PRODUCT_ID: u16 = 0x6401;
/// USB product id of the DLPC900 (Pycrafter6500's `usb.core.find`).
pub const DLPC900_PRODUCT_ID: u16 = 0xC900;

/// Which controller a head has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Controller {
    /// DLPC350: images to flash slots, 3-byte LUT entries in a mailbox.
    Dlpc350,
    /// DLPC900: pattern on-the-fly, ERLE images, 12-byte LUT entries.
    Dlpc900,
}

impl Controller {
    /// The controller's model in `protocol` (its limits).
    pub fn model(self) -> ProjectorModel {
        match self {
            Controller::Dlpc350 => ProjectorModel::Dlpc350,
            Controller::Dlpc900 => ProjectorModel::Dlpc900,
        }
    }

    /// Name as TI spells it.
    pub fn name(self) -> &'static str {
        match self {
            Controller::Dlpc350 => "DLPC350",
            Controller::Dlpc900 => "DLPC900",
        }
    }
}

/// The byte transport: 65-byte reports out (report id first), 64-byte
/// reports in.
pub trait HidLink {
    /// Sends one report.
    fn write(&mut self, report: &[u8; REPORT_LEN]) -> Result<(), LinkError>;
    /// Waits up to `timeout_ms` for one report from the device.
    fn read(&mut self, timeout_ms: u32) -> Result<[u8; REPLY_LEN], LinkError>;
}

/// The transport failed (as opposed to the controller refusing).
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The device is gone (unplugged, or its handle closed).
    #[error("device disconnected")]
    Disconnected,
    /// No report within the timeout.
    #[error("no reply within {timeout_ms} ms")]
    Timeout {
        /// The timeout.
        timeout_ms: u32,
    },
    /// The HID library failed.
    #[error("HID backend")]
    Backend(#[source] Box<dyn std::error::Error + Send + Sync>),
}

/// What can go wrong driving a controller.
#[derive(Debug, thiserror::Error)]
pub enum DlpcError {
    /// The set breaks the controller's limits; nothing was sent.
    #[error("{controller}: pattern set refused before upload")]
    Limits {
        /// Controller name.
        controller: &'static str,
        /// Which limit.
        source: ControllerLimitError,
    },
    /// The plan asks of the loaded set what the controller cannot show;
    /// the board was not started.
    #[error("{controller}: plan refused before the board starts")]
    Plan {
        /// Controller name.
        controller: &'static str,
        /// Which slot, and why.
        source: ControllerLimitError,
    },
    /// An LED setting other than each LED fully on or off (the LUT selects
    /// LEDs, it does not dim them).
    #[error("pattern {pattern}: LEDs {led:?} are not each 0 or 1")]
    LedLevel {
        /// Pattern index.
        pattern: usize,
        /// The setting.
        led: Led,
    },
    /// The link failed while sending `command`.
    #[error("link failed at command {command:#06x} (message {message} of {messages})")]
    Link {
        /// The command being sent or answered.
        command: u16,
        /// Its place in the load, 1-based.
        message: usize,
        /// Messages of the load.
        messages: usize,
        /// The transport's error.
        source: LinkError,
    },
    /// The controller answered something unreadable.
    #[error("unreadable reply to command {command:#06x}")]
    Reply {
        /// The command answered.
        command: u16,
        /// What is wrong with it.
        source: ReplyError,
    },
    /// The controller refused a command (nack); `error_code` is the
    /// DLPC900's last error code where it was read.
    #[error("controller refused command {command:#06x} (error code {error_code:?})")]
    Refused {
        /// The refused command.
        command: u16,
        /// The DLPC900's error code (0x0100), if read.
        error_code: Option<u8>,
    },
    /// LUT validation reported errors (status bits 0..5 of 0x1A1A).
    #[error("pattern LUT validation failed: status {status:#04x}")]
    Validation {
        /// The status byte.
        status: u8,
    },
    /// A message too long to frame (a bug in a builder).
    #[error(transparent)]
    Message(#[from] MessageTooLong),
}

/// How a head's controller runs its sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriverConfig {
    /// Exposure (= pattern period) of every pattern, microseconds.
    pub exposure_us: u32,
    /// TRIG_IN_1 delay, nanoseconds.
    pub trigger_in_delay_ns: u32,
    /// Invert TRIG_OUT_1.
    pub trigger_out_invert: bool,
    /// LED PWM currents (red, green, blue), 0..=255.
    pub led_current: [u8; 3],
    /// How long to wait for each reply, milliseconds.
    pub reply_timeout_ms: u32,
}

impl DriverConfig {
    /// Patterns shown `exposure_us` each, no trigger delay, full LEDs.
    pub fn new(exposure_us: u32) -> Self {
        DriverConfig {
            exposure_us,
            trigger_in_delay_ns: 0,
            trigger_out_invert: false,
            led_current: [255; 3],
            reply_timeout_ms: 2000,
        }
    }
}

/// What the builders need of one load.
#[derive(Clone, Debug)]
pub struct SequenceSetup {
    /// Bits per pattern.
    pub bit_depth: u8,
    /// Per pattern: image index, bit position.
    pub slots: Vec<(u16, u8)>,
    /// Per pattern: LEDs.
    pub leds: Vec<Led>,
    /// Images uploaded.
    pub images: u16,
    /// Exposure of every pattern, microseconds.
    pub exposure_us: u32,
    /// TRIG_IN_1 delay, nanoseconds.
    pub trigger_in_delay_ns: u32,
    /// Invert TRIG_OUT_1.
    pub trigger_out_invert: bool,
    /// LED currents.
    pub led_current: [u8; 3],
}

/// LED select bits of the LUT (bit 0 red, 1 green, 2 blue); LEDs are
/// checked to be 0 or 1 before.
pub(crate) fn leds_bits(led: Led) -> u8 {
    led.iter()
        .enumerate()
        .map(|(i, &v)| u8::from(v >= 0.5) << i)
        .sum()
}

/// What one load sent and received.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UploadStats {
    /// Messages sent.
    pub messages: u64,
    /// 64-byte reports sent (the report id byte is not on the wire).
    pub reports_out: u64,
    /// 64-byte reports received (one ack or answer per message).
    pub reports_in: u64,
    /// Image bytes as the controller takes them (DLPC350 raw frames,
    /// DLPC900 ERLE with headers).
    pub image_bytes: u64,
    /// 24-bit images uploaded.
    pub images: u64,
}

impl UploadStats {
    /// Bytes on the wire, both directions, 64 per report.
    pub fn wire_bytes(&self) -> u64 {
        64 * (self.reports_out + self.reports_in)
    }

    /// Time at full-speed USB HID with a 1 ms interrupt interval: one
    /// 64-byte report per 1 ms frame and direction (USB 2.0 §5.7.3: a
    /// full-speed interrupt endpoint moves at most 64 bytes per
    /// transaction, one transaction per bInterval frame); a reply waits
    /// for its message, so out and in reports do not overlap.
    pub fn full_speed_hid_ms(&self) -> u64 {
        self.reports_out + self.reports_in
    }
}

/// The controller's identity.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Version {
    /// Application firmware: bits 31:24 major, 23:16 minor, 15:0 patch.
    pub app: u32,
    /// API version, same layout.
    pub api: u32,
}

/// The three status bytes (DLPU010 / DLPU018 §2.1 "status commands").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Status {
    /// Hardware status (bit 0 initialised, bits 3.. errors).
    pub hardware: u8,
    /// System status (bit 0 internal memory test passed).
    pub system: u8,
    /// Main status (bit 0 DMD parked, bit 1 sequencer running).
    pub main: u8,
}

/// One controller on one link.
pub struct DlpcHead<L: HidLink> {
    link: L,
    controller: Controller,
    limits: ControllerLimits,
    config: DriverConfig,
    seq: u8,
    loaded: Option<UploadStats>,
    loaded_set: Option<LoadedSet>,
}

impl<L: HidLink> DlpcHead<L> {
    /// A driver for `controller` on `link`, with the controller's data-sheet
    /// limits.
    pub fn new(link: L, controller: Controller, config: DriverConfig) -> Self {
        Self::with_limits(link, controller, controller.model().controller(), config)
    }

    /// A driver with other limits (a simulated controller whose DMD has the
    /// twin projector's size).
    pub fn with_limits(
        link: L,
        controller: Controller,
        limits: ControllerLimits,
        config: DriverConfig,
    ) -> Self {
        DlpcHead {
            link,
            controller,
            limits,
            config,
            seq: 0,
            loaded: None,
            loaded_set: None,
        }
    }

    /// The controller driven.
    pub fn controller(&self) -> Controller {
        self.controller
    }

    /// The limits loads are checked against.
    pub fn limits(&self) -> &ControllerLimits {
        &self.limits
    }

    /// What the last successful load sent; `None` while nothing is loaded
    /// (never loaded, or the last load failed part way).
    pub fn loaded(&self) -> Option<UploadStats> {
        self.loaded
    }

    /// The link (to inspect a simulated device).
    pub fn link(&self) -> &L {
        &self.link
    }

    /// The link, mutably (to throw a simulated device's fault switch).
    pub fn link_mut(&mut self) -> &mut L {
        &mut self.link
    }

    /// Sends one message, waits for its reply; a nack is
    /// [`DlpcError::Refused`] (with the DLPC900's error code).
    fn transact(
        &mut self,
        msg: &Message,
        stats: &mut UploadStats,
        place: (usize, usize),
    ) -> Result<Vec<u8>, DlpcError> {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let link_err = |source| DlpcError::Link {
            command: msg.command,
            message: place.0,
            messages: place.1,
            source,
        };
        for r in msg.reports(seq)? {
            self.link.write(&r).map_err(link_err)?;
            stats.reports_out += 1;
        }
        stats.messages += 1;
        let raw = self
            .link
            .read(self.config.reply_timeout_ms)
            .map_err(link_err)?;
        stats.reports_in += 1;
        let reply = parse_reply(&raw, Some(seq)).map_err(|source| DlpcError::Reply {
            command: msg.command,
            source,
        })?;
        if reply.nack {
            let error_code = match self.controller {
                Controller::Dlpc900 if msg.command != dlpc900::READ_ERROR_CODE => self
                    .transact(&Message::read(dlpc900::READ_ERROR_CODE, &[]), stats, place)
                    .ok()
                    .and_then(|d| d.first().copied()),
                _ => None,
            };
            return Err(DlpcError::Refused {
                command: msg.command,
                error_code,
            });
        }
        Ok(reply.data.to_vec())
    }

    fn read(&mut self, command: u16) -> Result<Vec<u8>, DlpcError> {
        self.transact(
            &Message::read(command, &[]),
            &mut UploadStats::default(),
            (1, 1),
        )
    }

    /// Reads the firmware version (0x0205: four u32, the first two kept).
    pub fn version(&mut self) -> Result<Version, DlpcError> {
        let d = self.read(dlpc350::GET_VERSION)?;
        let word = |i: usize| {
            d.get(i..i + 4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .ok_or(DlpcError::Reply {
                    command: dlpc350::GET_VERSION,
                    source: ReplyError::Length {
                        claimed: i + 4,
                        available: d.len(),
                    },
                })
        };
        Ok(Version {
            app: word(0)?,
            api: word(4)?,
        })
    }

    /// Reads the hardware, system and main status bytes.
    pub fn status(&mut self) -> Result<Status, DlpcError> {
        let mut byte = |command| -> Result<u8, DlpcError> {
            self.read(command)?
                .first()
                .copied()
                .ok_or(DlpcError::Reply {
                    command,
                    source: ReplyError::Length {
                        claimed: 1,
                        available: 0,
                    },
                })
        };
        Ok(Status {
            hardware: byte(dlpc350::STATUS_HW)?,
            system: byte(dlpc350::STATUS_SYS)?,
            main: byte(dlpc350::STATUS_MAIN)?,
        })
    }

    /// The DLPC900's last error code (0x0100); `None` on a DLPC350, which
    /// reports errors only through the status bytes.
    pub fn error_code(&mut self) -> Result<Option<u8>, DlpcError> {
        match self.controller {
            Controller::Dlpc900 => Ok(self.read(dlpc900::READ_ERROR_CODE)?.first().copied()),
            Controller::Dlpc350 => Ok(None),
        }
    }

    /// Checks `patterns` (values in [0, 1], one LED setting each) against
    /// the limits, then stops the sequence, uploads images and LUT,
    /// validates and starts it in external-trigger mode.
    pub fn load(
        &mut self,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<UploadStats, DlpcError> {
        let name = self.controller.name();
        let limit = |source| DlpcError::Limits {
            controller: name,
            source,
        };
        let dmd = self.limits.dmd_px;
        if let Some(p) = patterns
            .iter()
            .find(|p| p.size() != (dmd.0 as usize, dmd.1 as usize))
        {
            return Err(limit(ControllerLimitError::DmdSize {
                got: (p.width as u32, p.height as u32),
                dmd,
            }));
        }
        if let Some((pattern, led)) = leds
            .iter()
            .enumerate()
            .find(|(_, l)| l.iter().any(|&v| v != 0.0 && v != 1.0))
        {
            return Err(DlpcError::LedLevel { pattern, led: *led });
        }
        let bit_depth = packing::bit_depth_of(patterns);
        let images = patterns
            .len()
            .div_ceil(ControllerLimits::patterns_per_image(bit_depth) as usize);
        let frame_bytes = 3 * u64::from(dmd.0) * u64::from(dmd.1);
        // Stored bytes: DLPC350 raw frames in flash, DLPC900 decoded bit
        // planes (24 per image): 3 bytes per mirror per image either way.
        let stored = frame_bytes * images as u64;
        self.limits
            .check_set(
                patterns.len() as u32,
                bit_depth,
                self.config.exposure_us,
                stored,
            )
            .map_err(limit)?;
        if patterns.is_empty() {
            return Err(limit(ControllerLimitError::LutTooLong {
                patterns: 0,
                max: 0,
            }));
        }
        let packed = packing::pack(patterns, bit_depth, (u32::from(dmd.0), u32::from(dmd.1)));
        let setup = SequenceSetup {
            bit_depth,
            slots: packed.slots.clone(),
            leds: leds.to_vec(),
            images: packed.images.len() as u16,
            exposure_us: self.config.exposure_us,
            trigger_in_delay_ns: self.config.trigger_in_delay_ns,
            trigger_out_invert: self.config.trigger_out_invert,
            led_current: self.config.led_current,
        };
        let mut stats = UploadStats {
            images: packed.images.len() as u64,
            ..UploadStats::default()
        };
        let mut messages = vec![Message::write(dlpc350::PAT_START_STOP, &[0])];
        match self.controller {
            Controller::Dlpc350 => {
                for (i, words) in packed.images.iter().enumerate() {
                    let frame = packing::raw_frame(words);
                    stats.image_bytes += frame.len() as u64;
                    messages.extend(dlpc350::image_upload(i as u16, &frame));
                }
                messages.extend(dlpc350::sequence(&setup));
            }
            Controller::Dlpc900 => {
                messages.push(Message::write(dlpc900::DISP_MODE, &[3]));
                messages.extend(dlpc900::lut(&setup));
                for (i, words) in packed.images.iter().enumerate() {
                    let encoded = packing::erle_image(words, packed.size_px);
                    stats.image_bytes += encoded.len() as u64;
                    messages.extend(dlpc900::image_upload(i as u16, &encoded));
                }
                messages.extend(dlpc900::triggers_and_leds(&setup));
            }
        }
        messages.push(Message::write(dlpc350::LUT_VALID, &[0]));
        // From the first byte sent, the controller's old set is gone.
        self.loaded = None;
        self.loaded_set = None;
        let total = messages.len() + 2;
        for (i, m) in messages.iter().enumerate() {
            self.transact(m, &mut stats, (i + 1, total))?;
        }
        // Validation runs in the controller: poll until bit 7 (busy) clears.
        let status = loop {
            let d = self.transact(
                &Message::read(dlpc350::LUT_VALID, &[]),
                &mut stats,
                (total - 1, total),
            )?;
            match d.first() {
                Some(s) if s & 0x80 == 0 => break *s,
                Some(_) => continue,
                None => {
                    return Err(DlpcError::Reply {
                        command: dlpc350::LUT_VALID,
                        source: ReplyError::Length {
                            claimed: 1,
                            available: 0,
                        },
                    })
                }
            }
        };
        if status & 0x1F != 0 {
            return Err(DlpcError::Validation { status });
        }
        self.transact(
            &Message::write(dlpc350::PAT_START_STOP, &[2]),
            &mut stats,
            (total, total),
        )?;
        self.loaded = Some(stats);
        self.loaded_set = Some(LoadedSet {
            patterns: patterns.len() as u32,
            bit_depth,
            exposure_us: self.config.exposure_us,
        });
        Ok(stats)
    }

    /// Checks head `head`'s slots of `plan` against the set this controller
    /// holds (none loaded: no slot may show a pattern).
    pub fn check_plan(&self, plan: &ScanPlan, head: usize) -> Result<(), DlpcError> {
        let set = self.loaded_set.unwrap_or(LoadedSet {
            patterns: 0,
            bit_depth: 1,
            exposure_us: 0,
        });
        plan.check_controller(head, &self.limits, &set)
            .map_err(|source| DlpcError::Plan {
                controller: self.controller.name(),
                source,
            })
    }
}

/// Checks `plan` against every head's controller, head `h` = `heads[h]`
/// (the hardware projector and the simulated rig's drivers alike).
pub fn check_plan_on_heads<L: HidLink>(
    heads: &[DlpcHead<L>],
    plan: &ScanPlan,
) -> Result<(), RigError> {
    for (head, h) in heads.iter().enumerate() {
        h.check_plan(plan, head)
            .map_err(|source| RigError::Controller { head, source })?;
    }
    Ok(())
}

/// DMD projectors driven through their controllers, one [`DlpcHead`] per
/// head.
pub struct DlpcProjector<L: HidLink> {
    heads: Vec<DlpcHead<L>>,
}

impl<L: HidLink> DlpcProjector<L> {
    /// Head `h` is `heads[h]`.
    pub fn new(heads: Vec<DlpcHead<L>>) -> Self {
        DlpcProjector { heads }
    }

    /// The drivers.
    pub fn heads(&self) -> &[DlpcHead<L>] {
        &self.heads
    }

    fn head_mut(&mut self, head: usize) -> Result<&mut DlpcHead<L>, RigError> {
        let heads = self.heads.len();
        self.heads
            .get_mut(head)
            .ok_or(RigError::NoSuchHead { head, heads })
    }
}

impl<L: HidLink> Projector for DlpcProjector<L> {
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        let h = self.heads.get(head).ok_or(RigError::NoSuchHead {
            head,
            heads: self.heads.len(),
        })?;
        Ok((u32::from(h.limits.dmd_px.0), u32::from(h.limits.dmd_px.1)))
    }

    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        self.load_coloured_sequence(head, patterns, &vec![WHITE; patterns.len()])
    }

    fn check_plan(&self, plan: &ScanPlan) -> Result<(), RigError> {
        check_plan_on_heads(&self.heads, plan)
    }

    fn load_coloured_sequence(
        &mut self,
        head: usize,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<(), RigError> {
        let dmd = self.dmd_size_px(head)?;
        check_sequence(head, dmd, patterns, leds)?;
        let h = self.head_mut(head)?;
        let stats = h
            .load(patterns, leds)
            .map_err(|source| RigError::Controller { head, source })?;
        tracing::info!(
            head,
            controller = h.controller.name(),
            images = stats.images,
            reports_out = stats.reports_out,
            full_speed_ms = stats.full_speed_hid_ms(),
            "pattern set uploaded"
        );
        Ok(())
    }
}
