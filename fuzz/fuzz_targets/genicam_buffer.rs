//! Any bytes as a GenICam camera's buffer (a device's stream is input from
//! outside the program): the first 9 bytes give the declared pixel format,
//! width and height (a camera's claims, which the bytes may not
//! back), the rest the image bytes, into
//! `slscan::rig::genicam::pixels::decode_frame` and, for the colour
//! formats (RGB8, BGR8, Bayer 8/12/16), `decode_colour_frame`; and the same bytes as a
//! stream's arrivals (id, stamps, status) into
//! `slscan::rig::genicam::ledger::check_arrivals`. No panic and no
//! allocation from a claimed size the bytes do not back; a decoded frame
//! holds width x height values in [0, 1]; a passing ledger has exactly the
//! expected count, all complete, ids consecutive.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slscan::rig::genicam::ledger::{check_arrivals, id_step, Arrival, ArrivalStatus};
use slscan::rig::genicam::pixels::{decode_colour_frame, decode_frame, PixelFormat};

fuzz_target!(|data: &[u8]| {
    if data.len() < 9 {
        return;
    }
    let format = PixelFormat::ALL[data[0] as usize % PixelFormat::ALL.len()];
    let width = u32::from(u16::from_le_bytes([data[1], data[2]])) << (data[3] & 15);
    let height = u32::from(u16::from_le_bytes([data[4], data[5]])) << (data[6] & 15);
    let bytes = &data[9..];
    if let Ok(frame) = decode_frame(format, width, height, bytes) {
        assert_eq!(frame.data.len(), width as usize * height as usize);
        assert!(frame.data.iter().all(|v| (0.0..=1.0).contains(v)));
    }
    if let Ok(planes) = decode_colour_frame(format, width, height, bytes) {
        assert!(format.is_colour());
        for plane in &planes {
            assert_eq!(plane.data.len(), width as usize * height as usize);
            // A Bayer mosaic one pixel wide or high, which would lack a
            // colour (NaN), is refused.
            assert!(plane.data.iter().all(|v| (0.0..=1.0).contains(v)));
        }
    }

    let expected = data[7] as usize % 16;
    let arrivals: Vec<Arrival> = bytes
        .chunks_exact(9)
        .map(|c| Arrival {
            frame_id: u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], 0])
                >> (c[6] & 63),
            device_ns: 0,
            host_ns: 0,
            status: match c[8] % 6 {
                0..=2 => ArrivalStatus::Complete,
                3 => ArrivalStatus::MissingPackets,
                4 => ArrivalStatus::TimedOut,
                _ => ArrivalStatus::SizeMismatch,
            },
        })
        .collect();
    if check_arrivals(&arrivals, expected).is_ok() {
        assert_eq!(arrivals.len(), expected);
        assert!(arrivals.iter().all(|a| a.status == ArrivalStatus::Complete));
        assert!(arrivals
            .windows(2)
            .all(|p| id_step(p[0].frame_id, p[1].frame_id) == 1));
    }
});
