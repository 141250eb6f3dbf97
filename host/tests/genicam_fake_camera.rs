//! The GenICam backend against a real GigE Vision device: Aravis's
//! `arv-fake-gv-camera-0.8` served on loopback (Debian `aravis-tools`),
//! spoken to over GVCP/GVSP by the same code that drives a real camera.
//!
//! The fake camera fills Mono8 frames with a known ramp, value
//! `(x + y + block id) mod 255` at exposure 10 ms and gain 0, so every
//! decoded frame is checked pixel for pixel against its own block id.
//!
//! One fake camera at a time (the runner waits for the one before): they all
//! bind the GVCP port 3956.

use std::thread::sleep;
use std::time::Duration;

use slscan::raster::Raster;
use slscan::rig::bayer::Cfa;
use slscan::rig::camera_source::FrameSource;
use slscan::rig::genicam::aravis_camera::{GenicamCamera, GenicamCameras};
use slscan::rig::genicam::{
    ArrivalStatus, GenicamError, GenicamSettings, LedgerError, PixelFormat,
};
use slscan::rig::RigError;

#[path = "support/fake_gv_camera.rs"]
mod fake_gv_camera;

use fake_gv_camera::FakeGvCamera;

fn settings(format: PixelFormat, trigger: &str) -> GenicamSettings {
    GenicamSettings {
        pixel_format: format,
        exposure_us: Some(10_000.0),
        gain: Some(0.0),
        roi: Some((0, 0, 640, 480)),
        trigger_source: trigger.into(),
        frame_timeout: Duration::from_millis(1500),
        ..GenicamSettings::default()
    }
}

/// Opens the fake camera `id` and lets it settle: its first frame after
/// AcquisitionStart comes incomplete (Mono16: 360 of 440 packets never
/// sent, with Aravis's own tools too), so one warm-up trigger goes first
/// and its frame is dropped by the next `arm`, as a rig's set-up would.
fn open_settled(id: &str, settings: &GenicamSettings) -> GenicamCamera {
    let camera =
        GenicamCamera::open(id, settings).expect("the fake camera opens and takes the settings");
    if settings.trigger_source == "Software" {
        sleep(Duration::from_millis(200));
        camera.software_trigger().unwrap();
        sleep(Duration::from_millis(300));
    }
    camera
}

/// Arms `camera` for `n` frames and fires `n` software triggers spaced so
/// the fake camera (which serves one trigger per 40 ms slot) sees each.
fn trigger(camera: &mut GenicamCamera, n: usize) {
    camera.arm(n);
    for _ in 0..n {
        camera.software_trigger().unwrap();
        sleep(Duration::from_millis(120));
    }
}

#[test]
fn triggered_mono8_frames_arrive_whole_in_order_with_time_stamps() {
    let fake = FakeGvCamera::start("SLT8", 0);
    let mut camera = open_settled(&fake.id, &settings(PixelFormat::Mono8, "Software"));
    assert_eq!(camera.image_size_px(), (640, 480));
    assert!(!camera.firmware_version().is_empty());

    let n = 12;
    trigger(&mut camera, n);
    let frames = camera.take_frames().expect("12 triggers give 12 frames");
    assert_eq!(frames.len(), n);
    let arrivals = camera.last_arrivals();
    for (frame, arrival) in frames.iter().zip(arrivals) {
        assert_eq!(arrival.status, ArrivalStatus::Complete);
        assert_eq!((frame.width, frame.height), (640, 480));
        // The fake camera's ramp, from this frame's own block id: the
        // bytes went through decoding unchanged and in trigger order.
        for &(x, y) in &[(0, 0), (17, 3), (639, 479), (254, 1)] {
            let expected = ((x + y + arrival.frame_id as usize) % 255) as f32 / 255.0;
            assert_eq!(
                *frame.at(x, y),
                expected,
                "frame {} pixel ({x}, {y})",
                arrival.frame_id
            );
        }
    }
    for pair in arrivals.windows(2) {
        assert!(
            pair[1].device_ns > pair[0].device_ns,
            "device time stamps increase"
        );
        assert!(
            pair[1].host_ns > pair[0].host_ns,
            "host time stamps increase"
        );
    }
    let counters = camera.last_counters();
    assert_eq!(counters.completed, n as u64);
    assert_eq!(counters.failures, 0);

    // A second plan on the same open camera counts only its own frames.
    trigger(&mut camera, 3);
    assert_eq!(camera.take_frames().unwrap().len(), 3);
}

#[test]
fn triggered_mono16_frames_arrive_with_the_mono16_payload() {
    let fake = FakeGvCamera::start("SLT16", 0);
    let mut camera = open_settled(&fake.id, &settings(PixelFormat::Mono16, "Software"));
    assert_eq!(camera.pixel_format(), PixelFormat::Mono16);
    trigger(&mut camera, 5);
    let frames = camera.take_frames().unwrap();
    assert_eq!(frames.len(), 5);
    assert!(frames.iter().all(
        |f| (f.width, f.height) == (640, 480) && f.data.iter().all(|v| (0.0..=1.0).contains(v))
    ));
}

#[test]
fn a_camera_that_never_triggers_is_a_typed_time_out() {
    let fake = FakeGvCamera::start("SLTL0", 0);
    // Line0 is never driven on the fake camera: the board's line is cut.
    let mut camera = GenicamCamera::open(&fake.id, &settings(PixelFormat::Mono8, "Line0")).unwrap();
    camera.arm(4);
    let err = camera.take_frames().unwrap_err();
    match err {
        GenicamError::Frames {
            waited_ms,
            source:
                LedgerError::TooFew {
                    expected: 4,
                    got: 0,
                },
            ..
        } => assert!(
            waited_ms >= 1500,
            "waited the frame time-out ({waited_ms} ms)"
        ),
        other => panic!("expected a time-out with 0 of 4 frames, got {other}"),
    }
}

/// With `lost` per thousand GVSP packets dropped by the camera, a plan of
/// 10 frames ends either whole (every loss recovered by resends, counted)
/// or in a typed error naming the frame: never a short scan.
fn lost_packets(serial: &str, lost: u32) {
    let fake = FakeGvCamera::start(serial, lost);
    let mut camera = open_settled(&fake.id, &settings(PixelFormat::Mono8, "Software"));
    let n = 10;
    trigger(&mut camera, n);
    let outcome = camera.take_frames();
    eprintln!(
        "{lost}/1000 packets lost: {} ; stream over the plan: {:?}",
        match &outcome {
            Ok(frames) => format!("{} whole frames", frames.len()),
            Err(e) => e.to_string(),
        },
        camera.last_counters()
    );
    match outcome {
        Ok(frames) => {
            assert_eq!(frames.len(), n);
            let counters = camera.last_counters();
            // 220 packets a frame at >= 1 % loss: losses are certain, so a
            // whole plan means the camera resent them.
            assert!(
                counters.resent_packets > 0,
                "whole frames at {lost}/1000 loss without resends: {counters:?}"
            );
        }
        Err(GenicamError::Frames { source, .. }) => {
            let message = source.to_string();
            match source {
                LedgerError::Incomplete { index, .. } => {
                    assert!(index < n);
                    assert!(message.contains(&format!("frame {index}")));
                }
                LedgerError::Gap { .. } | LedgerError::TooFew { .. } => {}
                other => panic!("unexpected ledger error {other}"),
            }
        }
        Err(other) => panic!("expected frames or a frame error, got {other}"),
    }
}

#[test]
fn one_percent_lost_packets_are_resent_or_named() {
    lost_packets("SLTR10", 10);
}

#[test]
fn five_percent_lost_packets_are_resent_or_named() {
    lost_packets("SLTR50", 50);
}

#[test]
fn an_unknown_id_and_an_unoffered_format_are_refused_by_name() {
    let fake = FakeGvCamera::start("SLTERR", 0);
    match GenicamCamera::open("No-Such-Camera", &GenicamSettings::default()) {
        Err(GenicamError::NotFound { id, found }) => {
            assert_eq!(id, "No-Such-Camera");
            assert!(found.contains(&fake.id), "{found:?}");
        }
        other => panic!("expected NotFound, got {:?}", other.err()),
    }
    // The fake camera offers Mono8 and Mono16, not Mono12.
    match GenicamCamera::open(&fake.id, &settings(PixelFormat::Mono12, "Software")) {
        Err(e @ GenicamError::PixelFormat { .. }) => {
            let message = e.to_string();
            assert!(
                message.contains("Mono12") && message.contains("Mono16"),
                "{message}"
            );
        }
        other => panic!("expected a pixel-format refusal, got {:?}", other.err()),
    }
}

/// Opens fake camera `serial` in `format` and takes `n` triggered frames
/// through the rig's frame source, as colour planes, with their block ids.
fn colour_frames(serial: &str, format: PixelFormat, n: usize) -> Vec<([Raster<f32>; 3], u64)> {
    let fake = FakeGvCamera::start(serial, 0);
    let camera = open_settled(&fake.id, &settings(format, "Software"));
    let mut cameras = GenicamCameras::new(vec![camera]);
    cameras.arm(&[n]).unwrap();
    for _ in 0..n {
        cameras.camera(0).unwrap().software_trigger().unwrap();
        sleep(Duration::from_millis(120));
    }
    let frames = cameras
        .take_colour_frames(0)
        .expect("one colour frame per trigger");
    let ids = cameras
        .camera(0)
        .unwrap()
        .last_arrivals()
        .iter()
        .map(|a| a.frame_id);
    frames.into_iter().zip(ids).collect()
}

#[test]
fn colour_frames_arrive_as_planes_from_rgb8_and_a_bayer_mosaic() {
    // The fake camera paints colour index (x + y + block id) mod 255 of a
    // jet colour map. RGB8 frames give the map (a row holds every index),
    // which then predicts every recorded sample of a Bayer frame: a wrong
    // channel order or mosaic phase reads another colour's value.
    let rgb = colour_frames("SLTRGB", PixelFormat::Rgb8, 3);
    assert_eq!(rgb.len(), 3);
    let (planes, id) = &rgb[0];
    let map: Vec<[f32; 3]> = (0..255)
        .map(|index| {
            let x = (index + 255 - (*id % 255) as usize) % 255;
            [0, 1, 2].map(|c| *planes[c].at(x, 0))
        })
        .collect();
    // The map is a jet: blue at its low end, red at its high end.
    assert!(
        map[0][0] == 0.0 && map[0][1] == 0.0 && map[0][2] > 0.5,
        "{:?}",
        map[0]
    );
    assert!(
        map[254][0] > 0.5 && map[254][1] == 0.0 && map[254][2] == 0.0,
        "{:?}",
        map[254]
    );
    for (planes, id) in &rgb {
        for &(x, y) in &[(0, 0), (17, 3), (639, 479), (300, 200)] {
            let index = (x + y + *id as usize) % 255;
            let got = [0, 1, 2].map(|c| *planes[c].at(x, y));
            assert_eq!(got, map[index], "RGB8 frame {id} ({x}, {y})");
        }
    }
    // BayerGR8 (the fake camera's RG8 and BG8 mosaics have red and blue
    // swapped against PFNC's layout; its GR8 and GB8 follow it).
    let cfa = Cfa::Gr;
    for (planes, id) in colour_frames("SLTBAY", PixelFormat::Bayer8(cfa), 3) {
        for plane in &planes {
            assert_eq!((plane.width, plane.height), (640, 480));
            assert!(plane.data.iter().all(|v| (0.0..=1.0).contains(v)));
        }
        for y in [0, 1, 2, 3, 200, 479] {
            for x in [0, 1, 2, 3, 301, 639] {
                let c = cfa.colour_at(x, y);
                let want = map[(x + y + id as usize) % 255][c];
                assert_eq!(
                    *planes[c].at(x, y),
                    want,
                    "Bayer frame {id} ({x}, {y}) colour {c}"
                );
            }
        }
    }

    // A monochrome camera has no colour frames: a typed error before any
    // frame is read.
    let fake = FakeGvCamera::start("SLTMONO", 0);
    let camera = open_settled(&fake.id, &settings(PixelFormat::Mono8, "Software"));
    let mut cameras = GenicamCameras::new(vec![camera]);
    cameras.arm(&[1]).unwrap();
    assert!(matches!(
        cameras.take_colour_frames(0),
        Err(RigError::NotColour { head: 0 })
    ));
}
