//! The DLPC350 and DLPC900 drivers (`slscan::rig::dlpc`) against hil-sim's
//! byte-level controllers: what an upload costs on the wire, that the DMD
//! then shows exactly the patterns sent, and the refusals (over memory,
//! exposure under the minimum, device unplugged mid-upload, a plan whose
//! slots the loaded set cannot follow).
//!
//! `cargo test -p slscan --test dlpc_upload -- --nocapture` prints the
//! upload table.

use slscan::raster::Raster;
use slscan::rig::dlpc::{Controller, DlpcError, DriverConfig, LinkError};
use slscan::rig::WHITE;
use slscan::sim::dlpc::{shown, simulated_head};

/// The controller's own DMD size.
fn dmd(c: Controller) -> (u32, u32) {
    let (w, h) = c.model().controller().dmd_px;
    (u32::from(w), u32::from(h))
}

/// 12 8-bit fringes: 3 periods x 4 steps, 8-bit grey (as the scan's).
fn fringes_8bit(size: (u32, u32)) -> Vec<Raster<f32>> {
    slscan::scan::plan::fringe_sequence(size, &[24.0, 21.0, 18.0], 4)
}

/// 24 1-bit patterns: Gray-code-like column stripes and their inverses.
fn stripes_1bit(size: (u32, u32)) -> Vec<Raster<f32>> {
    (0..24)
        .map(|k| {
            let period = 2u32 << (k / 2).min(10);
            let mut r = Raster::filled(size.0 as usize, size.1 as usize, 0.0);
            for y in 0..size.1 as usize {
                for x in 0..size.0 as usize {
                    let on = (x as u32 / (period / 2)) % 2 == 1;
                    r.data[y * size.0 as usize + x] = f32::from(u8::from(on != (k % 2 == 1)));
                }
            }
            r
        })
        .collect()
}

#[test]
fn uploads_reach_the_dmd_exactly_and_their_cost_is_printed() {
    println!(
        "| controller | set | DMD | images | image bytes | reports out | reports in | wire bytes | full-speed HID time |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for c in [Controller::Dlpc350, Controller::Dlpc900] {
        let size = dmd(c);
        for (name, set, exposure_us) in [
            ("12 x 8-bit", fringes_8bit(size), 10_000),
            ("24 x 1-bit", stripes_1bit(size), 1_000),
        ] {
            let mut head = simulated_head(c, size, DriverConfig::new(exposure_us));
            let leds = vec![WHITE; set.len()];
            let stats = head.load(&set, &leds).expect("upload");
            assert_eq!(head.loaded(), Some(stats));
            let on_dmd = shown(&head);
            assert_eq!(on_dmd.len(), set.len());
            for (k, (p, s)) in set.iter().zip(&on_dmd).enumerate() {
                assert!(p.data == s.values, "{name} pattern {k} differs on the DMD");
                assert_eq!(s.led, [true; 3]);
            }
            println!(
                "| {} | {name} | {}x{} | {} | {} | {} | {} | {} | {:.1} s |",
                c.name(),
                size.0,
                size.1,
                stats.images,
                stats.image_bytes,
                stats.reports_out,
                stats.reports_in,
                stats.wire_bytes(),
                stats.full_speed_hid_ms() as f64 / 1000.0
            );
            let version = head.version().unwrap();
            assert_eq!(version.app >> 24, 3);
            assert_eq!(
                head.status().unwrap().main & 0x02,
                0x02,
                "sequencer running"
            );
        }
    }
}

#[test]
fn six_grey_patterns_in_two_images_show_in_order_through_the_two_entry_image_lut() {
    for c in [Controller::Dlpc350, Controller::Dlpc900] {
        let size = (64, 32);
        let mut head = simulated_head(c, size, DriverConfig::new(10_000));
        let set: Vec<Raster<f32>> = (0..6)
            .map(|k| Raster::filled(64, 32, (10 * k + 5) as f32 / 255.0))
            .collect();
        head.load(&set, &[WHITE; 6]).unwrap();
        let levels: Vec<f32> = shown(&head).iter().map(|p| p.values[0]).collect();
        let want: Vec<f32> = set.iter().map(|p| p.data[0]).collect();
        assert_eq!(levels, want, "{}", c.name());
    }
}

#[test]
fn a_set_over_the_controllers_memory_is_refused_before_any_byte() {
    // 51 8-bit patterns = 17 images; the DLPC900 holds 16 (400 bit planes).
    let c = Controller::Dlpc900;
    let size = (64, 32);
    let mut head = simulated_head(c, size, DriverConfig::new(10_000));
    let set = vec![Raster::filled(64, 32, 0.5); 51];
    let err = head.load(&set, &vec![WHITE; 51]).unwrap_err();
    println!(
        "over memory: {err}: {}",
        std::error::Error::source(&err).unwrap()
    );
    assert!(matches!(
        err,
        DlpcError::Limits {
            source: protocol::ControllerLimitError::OverMemory {
                images: 17,
                max_images: 16,
                ..
            },
            ..
        }
    ));
    assert_eq!(head.link().device().reports_in(), 0, "nothing sent");
}

#[test]
fn an_exposure_under_the_bit_depths_minimum_is_refused_before_any_byte() {
    // DLPC350 8-bit patterns need 8333 us; 1-bit ones 235 us.
    let c = Controller::Dlpc350;
    let mut head = simulated_head(c, (64, 32), DriverConfig::new(5_000));
    let grey = vec![Raster::filled(64, 32, 0.5); 3];
    let err = head.load(&grey, &[WHITE; 3]).unwrap_err();
    println!(
        "exposure: {err}: {}",
        std::error::Error::source(&err).unwrap()
    );
    assert!(matches!(
        err,
        DlpcError::Limits {
            source: protocol::ControllerLimitError::ExposureTooShort {
                bit_depth: 8,
                exposure_us: 5_000,
                min_us: 8_333
            },
            ..
        }
    ));
    assert_eq!(head.link().device().reports_in(), 0);
    // The same exposure is fine for 1-bit patterns.
    let binary = vec![Raster::filled(64, 32, 1.0); 3];
    head.load(&binary, &[WHITE; 3]).unwrap();
}

#[test]
fn unplugged_mid_upload_is_a_link_error_and_nothing_is_loaded() {
    for c in [Controller::Dlpc350, Controller::Dlpc900] {
        let size = (128, 64);
        let mut head = simulated_head(c, size, DriverConfig::new(10_000));
        let set = fringes_8bit(size);
        head.load(&set, &[WHITE; 12]).unwrap();
        let before = head.link().device().reports_in();
        // A second upload: the cable goes 40 reports in, inside the images.
        head.link_mut().device_mut().unplug_after(before + 40);
        let err = head.load(&set, &[WHITE; 12]).unwrap_err();
        println!("{}: unplugged: {err}", c.name());
        assert!(
            matches!(
                err,
                DlpcError::Link {
                    source: LinkError::Disconnected,
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(head.loaded(), None, "a half-loaded set is not claimed");
        assert!(shown(&head).is_empty());
        assert!(head.status().is_err());
    }
}

#[test]
fn a_plan_faster_or_longer_than_the_loaded_set_is_refused_before_the_board_starts() {
    use protocol::ControllerLimitError;
    use protocol::HeadSet;
    use slscan::scan::plan::one_pattern_per_scaled_exposure;
    let c = Controller::Dlpc350;
    let size = (64, 32);
    let mut head = simulated_head(c, size, DriverConfig::new(10_000));
    let standard = one_pattern_per_scaled_exposure(HeadSet::A, 12, 1.0).unwrap();
    // Nothing loaded yet: no slot may show a pattern.
    assert!(matches!(
        head.check_plan(&standard, 0),
        Err(DlpcError::Plan {
            source: ControllerLimitError::PatternNotLoaded { loaded: 0, .. },
            ..
        })
    ));
    head.load(&fringes_8bit(size), &[WHITE; 12]).unwrap();
    head.check_plan(&standard, 0)
        .expect("the scan's own plan fits the set it loaded");
    // A quarter exposure shows each 8-bit pattern 2.5 ms: under both the
    // set's 10 ms and the DLPC350's 8.333 ms minimum for 8 bits.
    let quarter = one_pattern_per_scaled_exposure(HeadSet::A, 12, 0.25).unwrap();
    let err = head.check_plan(&quarter, 0).unwrap_err();
    println!("plan: {err}: {}", std::error::Error::source(&err).unwrap());
    assert!(matches!(
        err,
        DlpcError::Plan {
            source: ControllerLimitError::SlotTooShort {
                exposure: 0,
                bit_depth: 8,
                min_us: 10_000,
                ..
            },
            ..
        }
    ));
    // A 13th pattern the controller does not hold.
    let longer = one_pattern_per_scaled_exposure(HeadSet::A, 13, 1.0).unwrap();
    assert!(matches!(
        head.check_plan(&longer, 0),
        Err(DlpcError::Plan {
            source: ControllerLimitError::PatternNotLoaded {
                exposure: 12,
                pattern_index: 12,
                loaded: 12
            },
            ..
        })
    ));
}
