//! DLPC350 (LightCrafter 4500) command builders: the messages of one
//! pattern-sequence upload, in the order DLPU010 §2.4.4 "Pattern Display"
//! and pyCrafter4500's `pattern_mode` send them. Numbers from TI's
//! `dlpc350_api.cpp` command table (as shipped in SLStudio's LC4500API).
//!
//! Images: the DLPC350 shows patterns from its flash (or its video port);
//! there is no RAM upload over USB. This driver writes the packed 24-bit
//! frames with the flash download commands (set address 0x0029, size
//! 0x002C, data 0x0025) into one image slot per frame of
//! [`IMAGE_SLOT_BYTES`]. On a real LightCrafter 4500 the images live inside
//! TI's firmware image (its GUI rebuilds and reflashes it, in programming
//! mode 0x3001): that layout is not implemented, so this image path runs
//! against hil-sim's controller only; the LUT, trigger, LED and sequence
//! commands are the documented ones.

use super::report::Message;
use super::{leds_bits, SequenceSetup};

/// Read: application, API, software-config and sequence-config versions (4 x u32).
pub const GET_VERSION: u16 = 0x0205;
/// Read: hardware status byte.
pub const STATUS_HW: u16 = 0x1A0A;
/// Read: system status byte.
pub const STATUS_SYS: u16 = 0x1A0B;
/// Read: main status byte.
pub const STATUS_MAIN: u16 = 0x1A0C;
/// LED enables: bit 3 sequencer-controlled, bits 0..3 red, green, blue.
pub const LED_ENABLE: u16 = 0x1A07;
/// LED PWM currents: red, green, blue.
pub const LED_CURRENT: u16 = 0x0B01;
/// Write 0: validate the pattern LUT; read: validation status (bit 7 busy).
pub const LUT_VALID: u16 = 0x1A1A;
/// Display mode: 0 video, 1 pattern.
pub const DISP_MODE: u16 = 0x1A1B;
/// Trigger out 1: invert, rising delay, falling delay.
pub const TRIG_OUT1_CTL: u16 = 0x1A1D;
/// Pattern data source: 0 video port, 3 flash.
pub const PAT_DISP_MODE: u16 = 0x1A22;
/// Pattern trigger mode: 1 = internal or external (TRIG_IN_1) trigger.
pub const PAT_TRIG_MODE: u16 = 0x1A23;
/// Sequence: 0 stop, 1 pause, 2 start.
pub const PAT_START_STOP: u16 = 0x1A24;
/// Exposure and frame period, u32 microseconds each.
pub const PAT_EXPO_PRD: u16 = 0x1A29;
/// LUT entries - 1, repeat, patterns per TRIG_OUT_2 - 1, images - 1.
pub const PAT_CONFIG: u16 = 0x1A31;
/// Mailbox offset.
pub const MBOX_ADDRESS: u16 = 0x1A32;
/// Mailbox: 0 close, 1 image index LUT, 2 pattern LUT.
pub const MBOX_CONTROL: u16 = 0x1A33;
/// Mailbox data.
pub const MBOX_DATA: u16 = 0x1A34;
/// TRIG_IN_1 delay, u32 in 107.2 ns steps.
pub const TRIG_IN1_DELAY: u16 = 0x1A35;
/// Flash address for the next download (u32).
pub const BL_SET_SECTADDR: u16 = 0x0029;
/// Bytes of the next download (u32).
pub const BL_SET_DNLDSIZE: u16 = 0x002C;
/// Download data.
pub const BL_DNLD_DATA: u16 = 0x0025;

/// Bytes reserved per image slot (a 912 x 1140 frame is 3,119,040 bytes).
pub const IMAGE_SLOT_BYTES: u32 = 4 * 1024 * 1024;
/// Data bytes per download message: the 512-byte message less the command.
pub const DOWNLOAD_CHUNK: usize = 510;
/// Pattern-number of the first 1-bit plane; 8-bit patterns are numbered
/// per byte (table 2-66: G, R, B planes); we keep our word layout.
const TRIGGER_EXTERNAL_POSITIVE: u8 = 1;

/// Flash download of one packed frame into image slot `slot`.
pub fn image_upload(slot: u16, frame: &[u8]) -> Vec<Message> {
    let mut out = vec![
        Message::write(
            BL_SET_SECTADDR,
            &(u32::from(slot) * IMAGE_SLOT_BYTES).to_le_bytes(),
        ),
        Message::write(BL_SET_DNLDSIZE, &(frame.len() as u32).to_le_bytes()),
    ];
    out.extend(
        frame
            .chunks(DOWNLOAD_CHUNK)
            .map(|c| Message::write(BL_DNLD_DATA, c)),
    );
    out
}

/// One pattern LUT entry (DLPU010 table 2-65; pyCrafter4500's
/// `send_pattern_lut`): byte 0 trigger type (bits 1:0) and pattern number
/// (bits 7:2), byte 1 bit depth (bits 3:0) and LEDs (bits 6:4), byte 2
/// invert / insert black / buffer swap / trigger-out-previous.
pub fn lut_entry(pattern_number: u8, bit_depth: u8, leds: u8, buffer_swap: bool) -> [u8; 3] {
    [
        TRIGGER_EXTERNAL_POSITIVE | (pattern_number << 2),
        bit_depth & 0x0F | (leds & 0x07) << 4,
        u8::from(buffer_swap) << 2,
    ]
}

/// The configuration messages after the images: source, trigger mode,
/// exposure, LUT sizes, image LUT, pattern LUT, triggers, LEDs.
pub fn sequence(setup: &SequenceSetup) -> Vec<Message> {
    let n = setup.slots.len();
    let images = setup.images as usize;
    let per_image = 24 / setup.bit_depth as usize;
    let mut out = vec![
        Message::write(DISP_MODE, &[1]),
        Message::write(PAT_DISP_MODE, &[3]),
        Message::write(PAT_TRIG_MODE, &[1]),
    ];
    let mut expo = setup.exposure_us.to_le_bytes().to_vec();
    expo.extend_from_slice(&setup.exposure_us.to_le_bytes());
    out.push(Message::write(PAT_EXPO_PRD, &expo));
    out.push(Message::write(
        PAT_CONFIG,
        &[(n - 1) as u8, 1, (n - 1).min(255) as u8, (images - 1) as u8],
    ));
    // Image index LUT: flash slots in display order. With exactly two
    // entries the controller reads them swapped, so TI's own API sends them
    // the other way round (dlpc350_api.cpp, DLPC350_SendImageLut, "special
    // case of 2 entries").
    let mut image_lut: Vec<u8> = (0..images as u8).collect();
    if image_lut.len() == 2 {
        image_lut.swap(0, 1);
    }
    out.extend([
        Message::write(MBOX_CONTROL, &[1]),
        Message::write(MBOX_ADDRESS, &[0]),
        Message::write(MBOX_DATA, &image_lut),
        Message::write(MBOX_CONTROL, &[0]),
    ]);
    let mut lut = Vec::with_capacity(3 * n);
    for (k, (&(_, bit), leds)) in setup.slots.iter().zip(&setup.leds).enumerate() {
        let number = bit / setup.bit_depth;
        lut.extend(lut_entry(
            number,
            setup.bit_depth,
            leds_bits(*leds),
            k % per_image == 0 && k > 0,
        ));
    }
    out.extend([
        Message::write(MBOX_CONTROL, &[2]),
        Message::write(MBOX_ADDRESS, &[0]),
        Message::write(MBOX_DATA, &lut),
        Message::write(MBOX_CONTROL, &[0]),
    ]);
    out.push(Message::write(
        TRIG_OUT1_CTL,
        &[u8::from(setup.trigger_out_invert), 0, 0],
    ));
    // 107.2 ns per step (dlpc350_api.cpp, DLPC350_SetTrigIn1Delay).
    let delay = ((f64::from(setup.trigger_in_delay_ns) / 107.2).round() as u32) & 0x7FFFF;
    out.push(Message::write(TRIG_IN1_DELAY, &delay.to_le_bytes()));
    out.push(Message::write(LED_CURRENT, &setup.led_current));
    out.push(Message::write(LED_ENABLE, &[0x08]));
    out
}
