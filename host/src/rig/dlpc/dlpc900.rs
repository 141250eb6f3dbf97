//! DLPC900 (LightCrafter 6500 / 9000) command builders: pattern on-the-fly
//! mode, as DLPU018 §2.4 "Pattern On-The-Fly" orders it and Pycrafter6500
//! (`defsequence`) sends it: stop, mode 3, one 0x1A34 per LUT entry, 0x1A31,
//! then each image as 0x1A2A (index, size) and 0x1A2B chunks, validate,
//! start.

use super::report::Message;
use super::{leds_bits, SequenceSetup};

/// Read: firmware versions.
pub const GET_VERSION: u16 = 0x0205;
/// Read: the last error code (one byte, 0 = none).
pub const READ_ERROR_CODE: u16 = 0x0100;
/// Read: hardware status byte.
pub const STATUS_HW: u16 = 0x1A0A;
/// Read: system status byte.
pub const STATUS_SYS: u16 = 0x1A0B;
/// Read: main status byte.
pub const STATUS_MAIN: u16 = 0x1A0C;
/// LED enables.
pub const LED_ENABLE: u16 = 0x1A07;
/// LED PWM currents.
pub const LED_CURRENT: u16 = 0x0B01;
/// Write 0: validate; read: validation status (bit 7 busy).
pub const LUT_VALID: u16 = 0x1A1A;
/// Display mode: 0 video, 1 pre-stored pattern, 2 video pattern, 3 on-the-fly.
pub const DISP_MODE: u16 = 0x1A1B;
/// Trigger out 1: invert, rising delay (i16 us), falling delay (i16 us).
pub const TRIG_OUT1_CTL: u16 = 0x1A1D;
/// Sequence: 0 stop, 1 pause, 2 start.
pub const PAT_START_STOP: u16 = 0x1A24;
/// Image to load next: index (u16), compressed size (u32).
pub const PATMEM_LOAD_INIT: u16 = 0x1A2A;
/// Image bytes: length (u16) then up to 504 bytes.
pub const PATMEM_LOAD_DATA: u16 = 0x1A2B;
/// LUT configuration: entries (u16), repeat count (u32, 0 = forever).
pub const LUT_CONFIG: u16 = 0x1A31;
/// One LUT entry, 12 bytes.
pub const LUT_DEFINITION: u16 = 0x1A34;
/// TRIG_IN_1: delay (u16 us), polarity (0 rising).
pub const TRIG_IN1_CTL: u16 = 0x1A35;

/// Image bytes per 0x1A2B message (Pycrafter6500: 64 - 4 - 2 - 2 per
/// report, 504 per message).
pub const LOAD_CHUNK: usize = 504;

/// One LUT entry (DLPU018 0x1A34; Pycrafter6500's `definepattern`): index
/// u16, exposure u24 us, options (bit 0 clear after exposure, bits 3:1 bit
/// depth - 1, bits 6:4 LEDs, bit 7 wait for trigger), dark time u24 us,
/// trigger-out-2 byte, image index (bits 10:0) | bit position << 11.
pub fn lut_entry(
    index: u16,
    exposure_us: u32,
    bit_depth: u8,
    leds: u8,
    image: u16,
    bit: u8,
) -> [u8; 12] {
    let e = exposure_us.to_le_bytes();
    let options = 1 | (bit_depth - 1) << 1 | (leds & 7) << 4 | 0x80;
    let place = (image & 0x7FF) | u16::from(bit) << 11;
    let i = index.to_le_bytes();
    let p = place.to_le_bytes();
    [
        i[0], i[1], e[0], e[1], e[2], options, 0, 0, 0, 0, p[0], p[1],
    ]
}

/// The LUT messages (before the images).
pub fn lut(setup: &SequenceSetup) -> Vec<Message> {
    let mut out: Vec<Message> = setup
        .slots
        .iter()
        .zip(&setup.leds)
        .enumerate()
        .map(|(k, (&(image, bit), leds))| {
            Message::write(
                LUT_DEFINITION,
                &lut_entry(
                    k as u16,
                    setup.exposure_us,
                    setup.bit_depth,
                    leds_bits(*leds),
                    image,
                    bit,
                ),
            )
        })
        .collect();
    let mut config = (setup.slots.len() as u16).to_le_bytes().to_vec();
    config.extend_from_slice(&0u32.to_le_bytes());
    out.push(Message::write(LUT_CONFIG, &config));
    out
}

/// One ERLE-encoded image into pattern memory slot `index`.
pub fn image_upload(index: u16, encoded: &[u8]) -> Vec<Message> {
    let mut init = index.to_le_bytes().to_vec();
    init.extend_from_slice(&(encoded.len() as u32).to_le_bytes());
    let mut out = vec![Message::write(PATMEM_LOAD_INIT, &init)];
    for chunk in encoded.chunks(LOAD_CHUNK) {
        let mut data = (chunk.len() as u16).to_le_bytes().to_vec();
        data.extend_from_slice(chunk);
        out.push(Message::write(PATMEM_LOAD_DATA, &data));
    }
    out
}

/// Trigger and LED messages after the images.
pub fn triggers_and_leds(setup: &SequenceSetup) -> Vec<Message> {
    let delay_us = (setup.trigger_in_delay_ns / 1000).min(u32::from(u16::MAX)) as u16;
    let d = delay_us.to_le_bytes();
    vec![
        Message::write(
            TRIG_OUT1_CTL,
            &[u8::from(setup.trigger_out_invert), 0, 0, 0, 0],
        ),
        Message::write(TRIG_IN1_CTL, &[d[0], d[1], 0]),
        Message::write(LED_CURRENT, &setup.led_current),
        Message::write(LED_ENABLE, &[0x08]),
    ]
}
