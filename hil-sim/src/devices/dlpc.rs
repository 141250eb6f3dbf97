//! A DMD controller (TI DLPC350 or DLPC900) at the byte level: it takes the
//! 65-byte HID reports a host writes (report id, flags, sequence, length,
//! command, data, continuation reports), answers one 64-byte report per
//! message that asks for a reply, keeps the uploaded images and the pattern
//! LUT, and refuses what the real controller refuses (nack bit, the
//! DLPC900's error code, LUT validation status bits). What it would show,
//! pattern by pattern in LUT order, is [`DlpcSim::sequence`]: the simulated
//! rig lights the simulated DMD with exactly that.
//!
//! Its parser and image decoders are its own, written from the same
//! documents as the host's driver (DLPU010 for the DLPC350, DLPU018 for the
//! DLPC900), so a mistake on one side shows up as a refusal or as other
//! patterns on the mirrors, not as two halves agreeing on a bug.
//!
//! Fault switch: [`DlpcSim::unplug_after`] makes the device vanish after a
//! number of reports, mid-upload; it then answers nothing and forgets its
//! RAM (a power cycle), as a pulled cable does.

use std::collections::VecDeque;

use protocol::ControllerLimits;

/// Which controller is simulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DlpcKind {
    /// DLPC350: images in flash slots, mailbox LUTs, global exposure.
    Dlpc350,
    /// DLPC900: pattern on-the-fly, 12-byte LUT entries, ERLE images.
    Dlpc900,
}

/// The device is gone (the fault switch).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("controller unplugged")]
pub struct Unplugged;

/// One pattern as the controller would show it.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerPattern {
    /// Row-major mirror values in [0, 1] (level / (2^depth - 1)).
    pub values: Vec<f32>,
    /// Red, green, blue LED on.
    pub led: [bool; 3],
    /// Bits per pattern.
    pub bit_depth: u8,
}

/// Bytes per DLPC350 image slot in the flash address space (the host's
/// driver writes frame `i` at `i * IMAGE_SLOT_BYTES`).
pub const DLPC350_SLOT_BYTES: u32 = 4 * 1024 * 1024;

// DLPC900 error codes (DLPU018, "Read Error Code" 0x0100).
const ERR_INVALID_COMMAND: u8 = 0x03;
const ERR_NOT_ALLOWED: u8 = 0x05;
const ERR_INVALID_PARAMETER: u8 = 0x06;
const ERR_OUT_OF_RESOURCE: u8 = 0x08;
const ERR_BAD_COMPRESSION: u8 = 0x09;

/// The simulated controller.
#[derive(Clone, Debug)]
pub struct DlpcSim {
    kind: DlpcKind,
    limits: ControllerLimits,
    // A message being assembled from continuation reports: flags, seq,
    // declared length, text so far.
    pending: Option<(u8, u8, usize, Vec<u8>)>,
    replies: VecDeque<[u8; 64]>,
    reports_in: u64,
    unplug_after: Option<u64>,
    unplugged: bool,
    running: bool,
    valid: bool,
    validation_status: u8,
    error_code: u8,
    images: Vec<Option<Vec<u32>>>,
    // DLPC350
    flash_addr: u32,
    download_size: u32,
    download: Vec<u8>,
    mailbox: u8,
    mailbox_addr: usize,
    image_lut: Vec<u8>,
    pattern_lut: Vec<[u8; 3]>,
    pat_config: [u8; 4],
    exposure_us: u32,
    period_us: u32,
    // DLPC900
    lut: Vec<Option<[u8; 12]>>,
    lut_entries: u16,
    load: Option<(u16, usize, Vec<u8>)>,
}

impl DlpcSim {
    /// A controller of `kind` with `limits` (DMD size, LUT, memory).
    pub fn new(kind: DlpcKind, limits: ControllerLimits) -> Self {
        DlpcSim {
            kind,
            limits,
            pending: None,
            replies: VecDeque::new(),
            reports_in: 0,
            unplug_after: None,
            unplugged: false,
            running: false,
            valid: false,
            validation_status: 0,
            error_code: 0,
            images: vec![None; limits.max_images as usize],
            flash_addr: 0,
            download_size: 0,
            download: Vec::new(),
            mailbox: 0,
            mailbox_addr: 0,
            image_lut: Vec::new(),
            pattern_lut: Vec::new(),
            pat_config: [0; 4],
            exposure_us: 0,
            period_us: 0,
            lut: vec![None; limits.max_lut_entries as usize],
            lut_entries: 0,
            load: None,
        }
    }

    /// Unplugs the device once it has received `reports` reports in all.
    pub fn unplug_after(&mut self, reports: u64) {
        self.unplug_after = Some(reports);
    }

    /// Reports received so far.
    pub fn reports_in(&self) -> u64 {
        self.reports_in
    }

    /// Whether the sequence runs (validated and started).
    pub fn running(&self) -> bool {
        self.running
    }

    /// One report from the host (65 bytes: report id, then 64).
    pub fn write(&mut self, report: &[u8]) -> Result<(), Unplugged> {
        if self.unplugged {
            return Err(Unplugged);
        }
        if self.unplug_after.is_some_and(|n| self.reports_in >= n) {
            self.pull_cable();
            return Err(Unplugged);
        }
        self.reports_in += 1;
        let body = report.get(1..).unwrap_or(&[]);
        match self.pending.take() {
            Some((flags, seq, len, mut text)) => {
                text.extend_from_slice(&body[..body.len().min(len - text.len())]);
                self.after_chunk(flags, seq, len, text);
            }
            None => {
                if body.len() < 4 {
                    return Ok(());
                }
                let (flags, seq) = (body[0], body[1]);
                let len = u16::from_le_bytes([body[2], body[3]]) as usize;
                if !(2..=512).contains(&len) {
                    self.reply(flags, seq, true, &[]);
                    return Ok(());
                }
                let text = body[4..].iter().take(len).copied().collect();
                self.after_chunk(flags, seq, len, text);
            }
        }
        Ok(())
    }

    /// The next reply, if any.
    pub fn read(&mut self) -> Result<Option<[u8; 64]>, Unplugged> {
        if self.unplugged {
            return Err(Unplugged);
        }
        Ok(self.replies.pop_front())
    }

    fn pull_cable(&mut self) {
        let (kind, limits) = (self.kind, self.limits);
        *self = DlpcSim::new(kind, limits);
        self.unplugged = true;
    }

    fn after_chunk(&mut self, flags: u8, seq: u8, len: usize, text: Vec<u8>) {
        if text.len() < len {
            self.pending = Some((flags, seq, len, text));
            return;
        }
        let command = u16::from_le_bytes([text[0], text[1]]);
        let read = flags & 0x80 != 0;
        let result = if read {
            self.on_read(command)
        } else {
            self.on_write(command, &text[2..]).map(|()| Vec::new())
        };
        let (nack, data) = match result {
            Ok(d) => (false, d),
            Err(code) => {
                self.error_code = code;
                (true, Vec::new())
            }
        };
        if flags & 0x40 != 0 {
            self.reply(flags, seq, nack, &data);
        }
    }

    fn reply(&mut self, flags: u8, seq: u8, nack: bool, data: &[u8]) {
        let mut r = [0u8; 64];
        r[0] = (flags & 0x80) | 0x40 | if nack { 0x20 } else { 0 };
        r[1] = seq;
        let n = data.len().min(60);
        r[2..4].copy_from_slice(&(n as u16).to_le_bytes());
        r[4..4 + n].copy_from_slice(&data[..n]);
        self.replies.push_back(r);
    }

    fn on_read(&mut self, command: u16) -> Result<Vec<u8>, u8> {
        match command {
            0x0205 => {
                let mut v = Vec::new();
                for word in [0x0301_0000u32, 0x0200_0000, 0, 0] {
                    v.extend_from_slice(&word.to_le_bytes());
                }
                Ok(v)
            }
            0x1A0A => Ok(vec![0x01]),
            0x1A0B => Ok(vec![0x01]),
            0x1A0C => Ok(vec![u8::from(self.running) << 1]),
            0x1A1A => Ok(vec![self.validation_status]),
            0x0100 if self.kind == DlpcKind::Dlpc900 => {
                Ok(vec![std::mem::take(&mut self.error_code)])
            }
            _ => Err(ERR_INVALID_COMMAND),
        }
    }

    fn on_write(&mut self, command: u16, data: &[u8]) -> Result<(), u8> {
        let need = |n: usize| {
            if data.len() >= n {
                Ok(())
            } else {
                Err(ERR_INVALID_PARAMETER)
            }
        };
        // Every command but start/stop and status changes the sequence: the
        // controllers take them only while it is stopped.
        if self.running && command != 0x1A24 {
            return Err(ERR_NOT_ALLOWED);
        }
        match command {
            0x1A24 => {
                need(1)?;
                match data[0] {
                    0 | 1 => self.running = false,
                    2 if self.valid => self.running = true,
                    2 => return Err(ERR_NOT_ALLOWED),
                    _ => return Err(ERR_INVALID_PARAMETER),
                }
                return Ok(());
            }
            0x1A1A => {
                self.validate();
                return Ok(());
            }
            0x1A07 | 0x1A1D | 0x1A22 | 0x1A23 | 0x0B01 | 0x1A35 => {
                need(1)?;
                self.valid = false;
                return Ok(());
            }
            0x1A1B => {
                need(1)?;
                let most = if self.kind == DlpcKind::Dlpc350 { 1 } else { 3 };
                return if data[0] <= most {
                    Ok(())
                } else {
                    Err(ERR_INVALID_PARAMETER)
                };
            }
            _ => {}
        }
        self.valid = false;
        match (self.kind, command) {
            (DlpcKind::Dlpc350, 0x0029) => {
                need(4)?;
                self.flash_addr = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
                Ok(())
            }
            (DlpcKind::Dlpc350, 0x002C) => {
                need(4)?;
                self.download_size = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
                self.download.clear();
                Ok(())
            }
            (DlpcKind::Dlpc350, 0x0025) => self.download_data(data),
            (DlpcKind::Dlpc350, 0x1A29) => {
                need(8)?;
                self.exposure_us = u32::from_le_bytes([data[0], data[1], data[2], data[3]]);
                self.period_us = u32::from_le_bytes([data[4], data[5], data[6], data[7]]);
                Ok(())
            }
            (DlpcKind::Dlpc350, 0x1A31) => {
                need(4)?;
                self.pat_config.copy_from_slice(&data[..4]);
                Ok(())
            }
            (DlpcKind::Dlpc350, 0x1A33) => {
                need(1)?;
                if data[0] > 3 {
                    return Err(ERR_INVALID_PARAMETER);
                }
                self.mailbox = data[0];
                self.mailbox_addr = 0;
                if data[0] == 1 {
                    self.image_lut.clear();
                } else if data[0] == 2 {
                    self.pattern_lut.clear();
                }
                Ok(())
            }
            (DlpcKind::Dlpc350, 0x1A32) => {
                need(1)?;
                self.mailbox_addr = data[0] as usize;
                Ok(())
            }
            (DlpcKind::Dlpc350, 0x1A34) => self.mailbox_data(data),
            (DlpcKind::Dlpc900, 0x1A34) => {
                need(12)?;
                let index = u16::from_le_bytes([data[0], data[1]]) as usize;
                let slot = self.lut.get_mut(index).ok_or(ERR_OUT_OF_RESOURCE)?;
                let mut entry = [0u8; 12];
                entry.copy_from_slice(&data[..12]);
                *slot = Some(entry);
                Ok(())
            }
            (DlpcKind::Dlpc900, 0x1A31) => {
                need(6)?;
                let n = u16::from_le_bytes([data[0], data[1]]);
                if n == 0 || n > self.limits.max_lut_entries {
                    return Err(ERR_OUT_OF_RESOURCE);
                }
                self.lut_entries = n;
                Ok(())
            }
            (DlpcKind::Dlpc900, 0x1A2A) => {
                need(6)?;
                let index = u16::from_le_bytes([data[0], data[1]]);
                let size = u32::from_le_bytes([data[2], data[3], data[4], data[5]]) as usize;
                if index >= self.limits.max_images {
                    return Err(ERR_OUT_OF_RESOURCE);
                }
                self.images[index as usize] = None;
                self.load = Some((index, size, Vec::with_capacity(size)));
                Ok(())
            }
            (DlpcKind::Dlpc900, 0x1A2B) => {
                need(2)?;
                let n = u16::from_le_bytes([data[0], data[1]]) as usize;
                let chunk = data.get(2..2 + n).ok_or(ERR_INVALID_PARAMETER)?;
                let (index, size, mut buf) = self.load.take().ok_or(ERR_NOT_ALLOWED)?;
                if buf.len() + n > size {
                    return Err(ERR_INVALID_PARAMETER);
                }
                buf.extend_from_slice(chunk);
                if buf.len() < size {
                    self.load = Some((index, size, buf));
                    return Ok(());
                }
                let words =
                    decode_dlpc900_image(&buf, self.dmd()).map_err(|_| ERR_BAD_COMPRESSION)?;
                self.images[index as usize] = Some(words);
                Ok(())
            }
            _ => Err(ERR_INVALID_COMMAND),
        }
    }

    fn dmd(&self) -> (usize, usize) {
        (self.limits.dmd_px.0 as usize, self.limits.dmd_px.1 as usize)
    }

    fn download_data(&mut self, data: &[u8]) -> Result<(), u8> {
        let size = self.download_size as usize;
        if self.download.len() + data.len() > size {
            return Err(ERR_INVALID_PARAMETER);
        }
        self.download.extend_from_slice(data);
        if self.download.len() < size {
            return Ok(());
        }
        let (w, h) = self.dmd();
        let slot = (self.flash_addr / DLPC350_SLOT_BYTES) as usize;
        let fits_memory =
            (slot as u64 + 1) * (3 * w * h) as u64 <= u64::from(self.limits.image_memory_bytes);
        if size != 3 * w * h
            || !self.flash_addr.is_multiple_of(DLPC350_SLOT_BYTES)
            || slot >= self.images.len()
            || !fits_memory
        {
            self.download.clear();
            return Err(ERR_OUT_OF_RESOURCE);
        }
        let words = self
            .download
            .chunks_exact(3)
            .map(|b| u32::from(b[0]) | u32::from(b[1]) << 8 | u32::from(b[2]) << 16)
            .collect();
        self.images[slot] = Some(words);
        self.download.clear();
        Ok(())
    }

    fn mailbox_data(&mut self, data: &[u8]) -> Result<(), u8> {
        match self.mailbox {
            1 => {
                if self.mailbox_addr + data.len() > self.limits.max_images as usize {
                    return Err(ERR_OUT_OF_RESOURCE);
                }
                self.image_lut.truncate(self.mailbox_addr);
                self.image_lut.extend_from_slice(data);
                // The DLPC350 reads a two-entry image LUT swapped (TI's
                // DLPC350_SendImageLut sends those two reversed for it).
                if self.image_lut.len() == 2 {
                    self.image_lut.swap(0, 1);
                }
                Ok(())
            }
            2 => {
                if !data.len().is_multiple_of(3)
                    || self.mailbox_addr + data.len() / 3 > self.limits.max_lut_entries as usize
                {
                    return Err(ERR_OUT_OF_RESOURCE);
                }
                self.pattern_lut.truncate(self.mailbox_addr);
                self.pattern_lut
                    .extend(data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
                Ok(())
            }
            _ => Err(ERR_NOT_ALLOWED),
        }
    }

    /// Runs LUT validation; status bit 0: an exposure or period the
    /// controller cannot show, bit 1: a pattern number or bit position out
    /// of range, bit 2: a LUT entry missing or the LUT length off its
    /// configuration, bit 3: an image the LUT names was not loaded (bits
    /// 2 and 3 are this simulator's, the guides name other causes there).
    fn validate(&mut self) {
        let mut status = 0u8;
        match self.kind {
            DlpcKind::Dlpc350 => {
                let n = self.pat_config[0] as usize + 1;
                if n != self.pattern_lut.len()
                    || self.image_lut.len() != self.pat_config[3] as usize + 1
                {
                    status |= 0x04;
                }
                let exposure_ok =
                    self.period_us == self.exposure_us || self.period_us >= self.exposure_us + 230;
                for e in &self.pattern_lut {
                    let depth = e[1] & 0x0F;
                    let min = self.limits.min_exposure_us(depth);
                    if min.is_err() || 24 / u32::from(depth.max(1)) <= u32::from(e[0] >> 2) {
                        status |= 0x02;
                    }
                    if !exposure_ok || min.is_ok_and(|m| self.exposure_us < m) {
                        status |= 0x01;
                    }
                }
                if self
                    .image_lut
                    .iter()
                    .any(|&i| self.images.get(i as usize).is_none_or(Option::is_none))
                {
                    status |= 0x08;
                }
            }
            DlpcKind::Dlpc900 => {
                for i in 0..self.lut_entries as usize {
                    let Some(e) = self.lut.get(i).copied().flatten() else {
                        status |= 0x04;
                        continue;
                    };
                    let exposure = u32::from_le_bytes([e[2], e[3], e[4], 0]);
                    let depth = ((e[5] >> 1) & 7) + 1;
                    let place = u16::from_le_bytes([e[10], e[11]]);
                    let (image, bit) = ((place & 0x7FF) as usize, (place >> 11) as u8);
                    if self
                        .limits
                        .min_exposure_us(depth)
                        .is_ok_and(|m| exposure < m)
                    {
                        status |= 0x01;
                    }
                    if bit % depth != 0 || bit + depth > 24 {
                        status |= 0x02;
                    }
                    if self.images.get(image).is_none_or(Option::is_none) {
                        status |= 0x08;
                    }
                }
                if self.lut_entries == 0 {
                    status |= 0x04;
                }
            }
        }
        self.validation_status = status;
        self.valid = status == 0;
    }

    /// What the controller shows, one entry per trigger in LUT order; empty
    /// unless the sequence runs.
    pub fn sequence(&self) -> Vec<ControllerPattern> {
        if !self.running {
            return Vec::new();
        }
        // (image index, first bit, depth, led bits) per LUT entry.
        let entries: Vec<(usize, u8, u8, u8)> = match self.kind {
            DlpcKind::Dlpc350 => {
                let mut cursor = 0usize;
                self.pattern_lut
                    .iter()
                    .map(|e| {
                        if e[2] & 0x04 != 0 {
                            cursor += 1;
                        }
                        let depth = e[1] & 0x0F;
                        let image = self.image_lut.get(cursor).copied().unwrap_or(0) as usize;
                        (image, (e[0] >> 2) * depth, depth, (e[1] >> 4) & 7)
                    })
                    .collect()
            }
            DlpcKind::Dlpc900 => (0..self.lut_entries as usize)
                .filter_map(|i| self.lut[i])
                .map(|e| {
                    let place = u16::from_le_bytes([e[10], e[11]]);
                    (
                        (place & 0x7FF) as usize,
                        (place >> 11) as u8,
                        ((e[5] >> 1) & 7) + 1,
                        (e[5] >> 4) & 7,
                    )
                })
                .collect(),
        };
        entries
            .into_iter()
            .map(|(image, bit, depth, leds)| {
                let words = self.images[image].as_deref().unwrap_or(&[]);
                let mask = (1u32 << depth) - 1;
                let full = mask as f32;
                ControllerPattern {
                    values: words
                        .iter()
                        .map(|w| ((w >> bit) & mask) as f32 / full)
                        .collect(),
                    led: [leds & 1 != 0, leds & 2 != 0, leds & 4 != 0],
                    bit_depth: depth,
                }
            })
            .collect()
    }
}

/// Why a DLPC900 image does not decode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ImageError {
    /// Header missing, wrong signature or size.
    #[error("bad image header")]
    Header,
    /// RLE (compression 1) is not simulated.
    #[error("compression {0} not supported")]
    Compression(u8),
    /// The stream ended early or a row did not add up to the width.
    #[error("corrupt ERLE stream at byte {0}")]
    Stream(usize),
}

/// Decodes a DLPC900 image (48-byte header: "Spld", width, height, bytes,
/// 8 reserved, background, reserved, compression at byte 25; then B G R pixels
/// or ERLE rows) into 24-bit words (R in bits 0..8, B in 16..24).
pub fn decode_dlpc900_image(bytes: &[u8], dmd: (usize, usize)) -> Result<Vec<u32>, ImageError> {
    if bytes.len() < 48 || &bytes[..4] != b"Spld" {
        return Err(ImageError::Header);
    }
    let w = u16::from_le_bytes([bytes[4], bytes[5]]) as usize;
    let h = u16::from_le_bytes([bytes[6], bytes[7]]) as usize;
    if (w, h) != dmd {
        return Err(ImageError::Header);
    }
    let pixel = |b: &[u8]| u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
    let body = &bytes[48..];
    match bytes[25] {
        0 => {
            if body.len() < 3 * w * h {
                return Err(ImageError::Stream(body.len()));
            }
            Ok(body.chunks_exact(3).take(w * h).map(pixel).collect())
        }
        2 => {
            let mut out: Vec<u32> = Vec::with_capacity(w * h);
            let mut i = 0usize;
            let byte = |i: &mut usize| -> Result<usize, ImageError> {
                let b = *body.get(*i).ok_or(ImageError::Stream(*i + 48))?;
                *i += 1;
                Ok(b as usize)
            };
            let count = |i: &mut usize| -> Result<usize, ImageError> {
                let b = byte(i)?;
                if b & 0x80 == 0 {
                    Ok(b)
                } else {
                    Ok((b & 0x7F) | byte(i)? << 7)
                }
            };
            for y in 0..h {
                let row_start = out.len();
                loop {
                    let at = i;
                    let first = body.get(i).copied().ok_or(ImageError::Stream(i + 48))?;
                    if first != 0 {
                        let n = count(&mut i)?;
                        let px = body.get(i..i + 3).ok_or(ImageError::Stream(i + 48))?;
                        i += 3;
                        out.extend(std::iter::repeat_n(pixel(px), n));
                    } else {
                        i += 1;
                        match byte(&mut i)? {
                            0 => break,
                            1 => {
                                let n = count(&mut i)?;
                                if y == 0 || n == 0 {
                                    return Err(ImageError::Stream(at + 48));
                                }
                                for _ in 0..n {
                                    let x = out.len() - row_start;
                                    if x >= w {
                                        return Err(ImageError::Stream(at + 48));
                                    }
                                    out.push(out[row_start - w + x]);
                                }
                            }
                            _ => {
                                i -= 1;
                                let n = count(&mut i)?;
                                let px =
                                    body.get(i..i + 3 * n).ok_or(ImageError::Stream(i + 48))?;
                                i += 3 * n;
                                out.extend(px.chunks_exact(3).map(pixel));
                            }
                        }
                    }
                    if out.len() - row_start > w {
                        return Err(ImageError::Stream(at + 48));
                    }
                }
                if out.len() - row_start != w {
                    return Err(ImageError::Stream(i + 48));
                }
            }
            if body.get(i..i + 3) != Some(&[0, 1, 0]) {
                return Err(ImageError::Stream(i + 48));
            }
            Ok(out)
        }
        c => Err(ImageError::Compression(c)),
    }
}

#[cfg(test)]
mod tests;
