//! Patterns -> the 24-bit images a DLPC controller stores, and the image
//! formats each one takes over USB.
//!
//! A 24-bit image carries 24 1-bit patterns or 3 8-bit patterns: pattern
//! `k` sits in image `k / n` at bit position `(k % n) * depth` of each
//! pixel's 24-bit word (n = 24 / depth), the layout of both controllers'
//! pattern LUTs (DLPU010 table 2-66 "pattern number" for the DLPC350, the
//! image index / bit position of DLPU018's 0x1A34 for the DLPC900).
//!
//! - DLPC350 frames go as 3 bytes per pixel, word little-endian, row-major
//!   ([`raw_frame`]).
//! - DLPC900 images go through pattern on-the-fly (0x1A2A / 0x1A2B) as a
//!   48-byte header and Enhanced Run-Length Encoding ([`erle_image`],
//!   DLPU018 §2.4.2 header, §2.4.3.2 ERLE; e841018/ERLE and
//!   Pycrafter6500's erle.py implement the same).

use crate::raster::Raster;

/// Bit depth and placement of a packed pattern set.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Packed {
    /// Bits per pattern (1 or 8).
    pub bit_depth: u8,
    /// Image width and height (the DMD's).
    pub size_px: (u32, u32),
    /// Per image, one 24-bit word per pixel, row-major.
    pub images: Vec<Vec<u32>>,
    /// Per pattern: (image index, bit position of its least significant bit).
    pub slots: Vec<(u16, u8)>,
}

/// The depth a set needs: 1 when every value is exactly 0 or 1, else 8.
pub fn bit_depth_of(patterns: &[Raster<f32>]) -> u8 {
    let binary = patterns
        .iter()
        .all(|p| p.data.iter().all(|&v| v == 0.0 || v == 1.0));
    if binary {
        1
    } else {
        8
    }
}

/// Packs `patterns` (all `size_px`, values in [0, 1]) at `bit_depth` (1 or
/// 8): grey is rounded to 8 bits (a DMD shows no finer grey), 1-bit
/// patterns are lit where the value is at least 0.5.
pub fn pack(patterns: &[Raster<f32>], bit_depth: u8, size_px: (u32, u32)) -> Packed {
    let per_image = 24 / bit_depth as usize;
    let pixels = size_px.0 as usize * size_px.1 as usize;
    let count = patterns.len().div_ceil(per_image);
    let mut images = vec![vec![0u32; pixels]; count];
    let mut slots = Vec::with_capacity(patterns.len());
    for (k, p) in patterns.iter().enumerate() {
        let (image, bit) = (k / per_image, ((k % per_image) * bit_depth as usize) as u8);
        slots.push((image as u16, bit));
        let words = &mut images[image];
        for (w, &v) in words.iter_mut().zip(&p.data) {
            let level = if bit_depth == 1 {
                u32::from(v >= 0.5)
            } else {
                (v.clamp(0.0, 1.0) * 255.0).round() as u32
            };
            *w |= level << bit;
        }
    }
    Packed {
        bit_depth,
        size_px,
        images,
        slots,
    }
}

/// A DLPC350 frame: 3 bytes per pixel (the word little-endian), row-major.
pub fn raw_frame(words: &[u32]) -> Vec<u8> {
    words
        .iter()
        .flat_map(|w| [*w as u8, (*w >> 8) as u8, (*w >> 16) as u8])
        .collect()
}

/// Bytes of the DLPC900 image header (DLPU018 §2.4.2).
pub const ERLE_HEADER_BYTES: usize = 48;

/// A DLPC900 image: header + ERLE rows + end-of-image, padded to 4 bytes,
/// the total length written into the header (offset 8, u32 LE).
///
/// Row codes (DLPU018 §2.4.3.2): `n, B G R` repeats a pixel n times;
/// `0, n, pixels` copies n literal pixels; `0, 1, n` copies n pixels from
/// the row above; `0, 0` ends a row; `0, 1, 0` ends the image. n above 127
/// takes two bytes (low 7 bits | 0x80, then n >> 7). Pixels go B, G, R:
/// the word's bits 16..24, 8..16, 0..8.
pub fn erle_image(words: &[u32], size_px: (u32, u32)) -> Vec<u8> {
    let (w, h) = (size_px.0 as usize, size_px.1 as usize);
    let mut out = Vec::with_capacity(ERLE_HEADER_BYTES + h * 8);
    out.extend_from_slice(&[0x53, 0x70, 0x6C, 0x64]); // "Spld"
    out.extend_from_slice(&(size_px.0 as u16).to_le_bytes());
    out.extend_from_slice(&(size_px.1 as u16).to_le_bytes());
    out.extend_from_slice(&[0; 4]); // total bytes, written below
    out.extend_from_slice(&[0xFF; 8]);
    out.extend_from_slice(&[0; 4]); // background colour
    out.extend_from_slice(&[0, 2, 1]); // reserved, compression 2 = ERLE, reserved
    out.extend_from_slice(&[0; 21]);
    debug_assert_eq!(out.len(), ERLE_HEADER_BYTES);
    for y in 0..h {
        let row = &words[y * w..(y + 1) * w];
        if y > 0 && row == &words[(y - 1) * w..y * w] {
            // The whole row as the one above: column fringes are all rows
            // alike, so an image costs little more than its first row.
            out.extend_from_slice(&[0, 1]);
            push_count(&mut out, w);
        } else {
            encode_row(&mut out, row);
        }
        out.extend_from_slice(&[0, 0]);
    }
    out.extend_from_slice(&[0, 1, 0]);
    while !out.len().is_multiple_of(4) {
        out.push(0);
    }
    let total = out.len() as u32;
    out[8..12].copy_from_slice(&total.to_le_bytes());
    out
}

fn push_count(out: &mut Vec<u8>, n: usize) {
    if n < 128 {
        out.push(n as u8);
    } else {
        out.push((n & 0x7F) as u8 | 0x80);
        out.push((n >> 7) as u8);
    }
}

fn push_pixel(out: &mut Vec<u8>, w: u32) {
    out.extend_from_slice(&[(w >> 16) as u8, (w >> 8) as u8, w as u8]);
}

// Counts stay under 2^14 (two count bytes), so runs are cut there.
const MAX_RUN: usize = (1 << 14) - 1;

fn encode_row(out: &mut Vec<u8>, row: &[u32]) {
    let mut x = 0;
    while x < row.len() {
        let run = row[x..]
            .iter()
            .take(MAX_RUN)
            .take_while(|&&v| v == row[x])
            .count();
        if run >= 2 {
            push_count(out, run);
            push_pixel(out, row[x]);
            x += run;
            continue;
        }
        // Literal pixels up to the next run of two.
        let mut end = x + 1;
        while end < row.len()
            && end - x < MAX_RUN
            && !(end + 1 < row.len() && row[end] == row[end + 1])
        {
            end += 1;
        }
        if end - x == 1 {
            out.push(1);
            push_pixel(out, row[x]);
        } else {
            out.push(0);
            push_count(out, end - x);
            for &v in &row[x..end] {
                push_pixel(out, v);
            }
        }
        x = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_bit_patterns_go_three_to_an_image_and_one_bit_twenty_four() {
        let grey: Vec<Raster<f32>> = (0..4)
            .map(|k| Raster::filled(2, 1, k as f32 * 50.0 / 255.0))
            .collect();
        let p = pack(&grey, 8, (2, 1));
        assert_eq!(p.images.len(), 2);
        assert_eq!(p.slots, vec![(0, 0), (0, 8), (0, 16), (1, 0)]);
        assert_eq!(p.images[0][0], 50 << 8 | 100 << 16);
        assert_eq!(p.images[1][1], 150);
        let bits: Vec<Raster<f32>> = (0..25)
            .map(|k| Raster::filled(1, 1, (k % 2) as f32))
            .collect();
        assert_eq!(bit_depth_of(&bits), 1);
        let p = pack(&bits, 1, (1, 1));
        assert_eq!(p.images.len(), 2);
        assert_eq!(p.slots[23], (0, 23));
        assert_eq!(p.images[0][0], 0xAA_AAAA);
        assert_eq!(raw_frame(&[0x0A_0B0C]), vec![0x0C, 0x0B, 0x0A]);
    }

    #[test]
    fn erle_codes_runs_literals_and_copied_rows() {
        let words = [5, 5, 5, 1, 2, 5, 5, 5, 1, 2];
        let e = erle_image(&words, (5, 2));
        assert_eq!(&e[..4], b"Spld");
        assert_eq!(
            u32::from_le_bytes([e[8], e[9], e[10], e[11]]) as usize,
            e.len()
        );
        assert_eq!(e[25], 2);
        let body = &e[ERLE_HEADER_BYTES..];
        #[rustfmt::skip]
        let want = [
            3, 0, 0, 5,            // 5 three times
            0, 2, 0, 0, 1, 0, 0, 2, // two literal pixels
            0, 0,                  // end of row
            0, 1, 5, 0, 0,         // row 2 = row 1, end of row
            0, 1, 0,               // end of image
        ];
        assert_eq!(&body[..want.len()], &want);
        assert_eq!(e.len() % 4, 0);
    }
}
