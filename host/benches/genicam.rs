//! Frame rates of the GenICam backend against Aravis's fake GigE Vision
//! camera on loopback (`arv-fake-gv-camera-0.8`, Debian `aravis-tools`),
//! 640x480 Mono8 and Mono16, printed as a table:
//!
//! - triggered: one plan of 40 software triggers 45 ms apart through
//!   `GenicamCamera` (arm, trigger, take), frames/s over the plan (the time
//!   to take them included) and the median time from a trigger to its
//!   frame's completion on the host; the fake camera serves one trigger per
//!   40 ms slot (its simulated trigger clock is 25 Hz), so the rate is
//!   bounded by the fake camera, not by slscan;
//! - free-running at the fake camera's highest AcquisitionFrameRate
//!   (1000 Hz) for 3 s: complete and incomplete frames/s received by the
//!   same Aravis stream set-up (loopback UDP, socket buffer sized to the
//!   payload), what the transport sustains on this machine;
//! - decoding: `pixels::decode_frame` of one such frame, frames/s (slscan's
//!   own per-frame cost after the stream).
//!
//! `cargo bench -p slscan --features genicam --bench genicam`

use std::thread::sleep;
use std::time::{Duration, Instant};

use aravis::prelude::*;
use slscan::rig::genicam::aravis_camera::GenicamCamera;
use slscan::rig::genicam::pixels::decode_frame;
use slscan::rig::genicam::{GenicamSettings, PixelFormat};

#[path = "../tests/support/fake_gv_camera.rs"]
mod fake_gv_camera;

use fake_gv_camera::FakeGvCamera;

/// Frames/s and median trigger-to-frame latency (ms) of `n` triggers.
fn triggered(id: &str, format: PixelFormat, n: usize) -> (f64, f64) {
    let settings = GenicamSettings {
        pixel_format: format,
        roi: Some((0, 0, 640, 480)),
        trigger_source: "Software".into(),
        frame_timeout: Duration::from_millis(1500),
        ..GenicamSettings::default()
    };
    let mut camera = GenicamCamera::open(id, &settings).expect("open");
    // The fake camera's first frame after AcquisitionStart is incomplete.
    sleep(Duration::from_millis(200));
    camera.software_trigger().unwrap();
    sleep(Duration::from_millis(300));
    // One plan of n triggers, 45 ms apart (just over the fake camera's
    // 40 ms trigger slot), then its frames taken at once.
    camera.arm(n);
    let mut sent_ns = Vec::with_capacity(n);
    let start = Instant::now();
    for _ in 0..n {
        sent_ns.push(now_ns());
        camera.software_trigger().unwrap();
        sleep(Duration::from_millis(45));
    }
    camera.take_frames().expect("one frame per trigger");
    let arrivals = camera.last_arrivals();
    let rate = n as f64 / start.elapsed().as_secs_f64();
    let mut latencies: Vec<f64> = arrivals
        .iter()
        .zip(&sent_ns)
        .map(|(a, &t)| (a.host_ns as f64 - t as f64) / 1e6)
        .collect();
    latencies.sort_by(f64::total_cmp);
    (rate, latencies[n / 2])
}

/// The wall clock in ns, the clock Aravis stamps buffers with on the host.
fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// Complete and incomplete frames/s of the free-running camera.
fn free_running(id: &str, format: PixelFormat, seconds: f64) -> (f64, f64) {
    let camera = aravis::Camera::new(Some(id)).expect("open");
    camera.gv_set_stream_options(aravis::GvStreamOption::PACKET_SOCKET_DISABLED);
    camera.set_region(0, 0, 640, 480).unwrap();
    camera.set_pixel_format_from_string(format.name()).unwrap();
    camera.set_string("TriggerMode", "Off").unwrap();
    camera.set_frame_rate(1000.0).unwrap();
    let payload = camera.payload().unwrap() as usize;
    let stream = camera.create_stream().unwrap();
    if let Some(gv) = aravis::glib::prelude::Cast::downcast_ref::<aravis::GvStream>(&stream) {
        gv.set_socket_buffer(aravis::GvStreamSocketBuffer::Auto);
    }
    for _ in 0..32 {
        stream.push_buffer(aravis::Buffer::new_allocate(payload));
    }
    camera.start_acquisition().unwrap();
    let (mut whole, mut broken) = (0u32, 0u32);
    let start = Instant::now();
    while start.elapsed().as_secs_f64() < seconds {
        if let Some(b) = stream.timeout_pop_buffer(200_000) {
            if b.status() == aravis::BufferStatus::Success {
                whole += 1;
            } else {
                broken += 1;
            }
            stream.push_buffer(b);
        }
    }
    let _ = camera.stop_acquisition();
    let s = start.elapsed().as_secs_f64();
    (whole as f64 / s, broken as f64 / s)
}

/// `decode_frame` of one 640x480 frame, frames/s.
fn decoding(format: PixelFormat) -> f64 {
    let bytes = vec![0x07u8; 640 * 480 * format.bytes_per_pixel()];
    let n = 200;
    let start = Instant::now();
    for _ in 0..n {
        std::hint::black_box(decode_frame(format, 640, 480, std::hint::black_box(&bytes)).unwrap());
    }
    n as f64 / start.elapsed().as_secs_f64()
}

fn main() {
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    println!("| 640x480 | triggered, 45 ms apart | median trigger -> frame complete | free-run whole | free-run incomplete | decode_frame |");
    println!("|---|---|---|---|---|---|");
    for (format, serial) in [
        (PixelFormat::Mono8, "BENCH8"),
        (PixelFormat::Mono16, "BENCH16"),
    ] {
        let fake = FakeGvCamera::start(serial, 0);
        let (rate, latency) = triggered(&fake.id, format, 40);
        let (whole, broken) = free_running(&fake.id, format, 3.0);
        println!(
            "| {} | {rate:.1} frames/s | {latency:.1} ms | {whole:.0} frames/s | {broken:.0} frames/s | {:.0} frames/s |",
            format.name(),
            decoding(format)
        );
    }
}
