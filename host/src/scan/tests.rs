//! What a scan refuses before it touches the rig.

use super::*;
use crate::calibration::{Head, PinholeModel, Pose};

fn rig(heads: usize, head_to_head: bool) -> RigCalibration {
    let head = |name: &str| Head {
        name: name.into(),
        camera: PinholeModel::ideal(64, 48, 80.0),
        projector: PinholeModel::ideal(128, 80, 120.0),
        view_errors: vec![],
        port: None,
    };
    RigCalibration {
        heads: ["A", "B", "C", "D", "E"]
            .iter()
            .take(heads)
            .map(|n| head(n))
            .collect(),
        head_poses: (1..heads)
            .filter(|_| head_to_head)
            .map(|_| Pose::identity())
            .collect(),
        stereo_heads: vec![],
    }
}

#[test]
fn rigs_and_modes_the_board_cannot_run_are_refused_by_name() {
    let config = ScanConfig::new("x");
    check_before_capture(&rig(1, false), &config).unwrap();
    check_before_capture(&rig(2, true), &config).unwrap();
    // Three and four heads scan sequentially and multiplexed; identical
    // sequences de-alias two projectors only.
    for heads in 3..=4 {
        check_before_capture(&rig(heads, true), &config).unwrap();
        let mut multiplexed = config.clone();
        multiplexed.mode = Mode::SimultaneousMultiplexed;
        check_before_capture(&rig(heads, true), &multiplexed).unwrap();
        let mut simultaneous = config.clone();
        simultaneous.mode = Mode::Simultaneous;
        simultaneous.periods_px = dealias_periods_px(1280);
        let err = check_before_capture(&rig(heads, true), &simultaneous).unwrap_err();
        assert!(
            matches!(err, ScanError::SimultaneousNeedsTwo { heads: h } if h == heads),
            "{err}"
        );
        let err = check_before_capture(&rig(heads, false), &config).unwrap_err();
        assert!(
            matches!(err, ScanError::NoHeadPoses { heads: h, poses: 0 } if h == heads),
            "{err}"
        );
    }
    let err = check_before_capture(&rig(5, true), &config).unwrap_err();
    assert!(matches!(err, ScanError::HeadCount { heads: 5 }), "{err}");
    assert!(
        err.to_string().contains("sync board drives 1 to 4"),
        "{err}"
    );
    assert!(matches!(
        check_before_capture(&rig(0, false), &config),
        Err(ScanError::HeadCount { heads: 0 })
    ));
    assert!(matches!(
        check_before_capture(&rig(2, false), &config),
        Err(ScanError::NoHeadPoses { heads: 2, poses: 0 })
    ));
    let mut simultaneous = config.clone();
    simultaneous.mode = Mode::Simultaneous;
    assert!(matches!(
        check_before_capture(&rig(1, false), &simultaneous),
        Err(ScanError::ModeNeedsTwoHeads { .. })
    ));
    // De-aliasing with the three default periods: too few.
    assert!(matches!(
        check_before_capture(&rig(2, true), &simultaneous),
        Err(ScanError::DealiasPeriods { periods: 3 })
    ));
    simultaneous.periods_px = dealias_periods_px(1280);
    check_before_capture(&rig(2, true), &simultaneous).unwrap();
    // Periods that cannot be projected, refused before any capture.
    for bad in [vec![], vec![0.0, 0.0, 0.0], vec![20.0, f64::NAN]] {
        let mut c = config.clone();
        c.periods_px = bad;
        assert!(matches!(
            check_before_capture(&rig(1, false), &c),
            Err(ScanError::BadPeriod { .. })
        ));
    }
    // Exposure kinds the mode or the plan cannot run, a bad saturation level.
    let mut c = config.clone();
    c.exposures = Exposures::Multi(vec![]);
    assert!(matches!(
        check_before_capture(&rig(1, false), &c),
        Err(ScanError::NoExposures)
    ));
    c.exposures = Exposures::Multi(vec![1.0, 100.0]);
    assert!(matches!(
        check_before_capture(&rig(1, false), &c),
        Err(ScanError::Plan(plan::PlanBuildError::ExposureScale { .. }))
    ));
    c.exposures = Exposures::AdaptiveHdr(crate::adaptive::hdr::HdrParams::default());
    check_before_capture(&rig(1, false), &c).unwrap();
    let mut bad = crate::adaptive::hdr::HdrParams::default();
    bad.rule.target = 1.5;
    c.exposures = Exposures::AdaptiveHdr(bad);
    assert!(matches!(
        check_before_capture(&rig(1, false), &c),
        Err(ScanError::Adaptive(_))
    ));
    let mut two = simultaneous.clone();
    two.exposures = Exposures::Multi(vec![1.0, 0.25]);
    assert!(matches!(
        check_before_capture(&rig(2, true), &two),
        Err(ScanError::ExposuresNeedSequential { .. })
    ));
    // Frame averaging: 1..=16, sequential fixed or auto exposures only.
    let mut c = config.clone();
    for frames in [0, MAX_FRAMES_PER_PATTERN + 1] {
        c.frames_per_pattern = frames;
        assert!(matches!(
            check_before_capture(&rig(1, false), &c),
            Err(ScanError::FramesPerPattern { .. })
        ));
    }
    c.frames_per_pattern = 4;
    check_before_capture(&rig(1, false), &c).unwrap();
    c.exposures = Exposures::AdaptiveHdr(crate::adaptive::hdr::HdrParams::default());
    assert!(matches!(
        check_before_capture(&rig(1, false), &c),
        Err(ScanError::FramesPerPattern { frames: 4, .. })
    ));
    let mut two = simultaneous.clone();
    two.frames_per_pattern = 2;
    assert!(matches!(
        check_before_capture(&rig(2, true), &two),
        Err(ScanError::FramesPerPattern { frames: 2, .. })
    ));
    let mut c = config.clone();
    c.saturation_level = 0.0;
    assert!(matches!(
        check_before_capture(&rig(1, false), &c),
        Err(ScanError::SaturationLevel(_))
    ));
    // Learned de-aliasing with no network loaded.
    simultaneous.dealias = crate::dealias::DealiasMethod::Learned;
    assert!(matches!(
        check_before_capture(&rig(2, true), &simultaneous),
        Err(ScanError::NoLearnedModel)
    ));
}

#[test]
fn a_water_scan_is_refused_without_a_port_on_every_head_and_outside_the_sequential_mode() {
    use crate::triangulation::flat_port::FlatPort;
    use underwater::{Medium, Restorer, WaterScan};
    let mut config = ScanConfig::new("x");
    config.medium = Medium::Water(WaterScan {
        turbidity: None,
        restorer: Restorer::Classical,
        psf_sigma_px: 2.0,
        edge_margin_sigmas: underwater::EDGE_MARGIN_SIGMAS,
    });
    let mut calibration = rig(2, true);
    let err = check_before_capture(&calibration, &config).unwrap_err();
    assert!(matches!(err, ScanError::NoPort { head: "A" }), "{err}");
    calibration.heads[0].port = Some(FlatPort::thin(0.03, 1.33).unwrap());
    let err = check_before_capture(&calibration, &config).unwrap_err();
    assert!(matches!(err, ScanError::NoPort { head: "B" }), "{err}");
    assert!(err.to_string().contains("\"port\""), "{err}");
    calibration.heads[1].port = calibration.heads[0].port;
    check_before_capture(&calibration, &config).unwrap();
    // In air the ports are not looked at.
    let air = ScanConfig::new("x");
    check_before_capture(&rig(2, true), &air).unwrap();

    let mut multiplexed = config.clone();
    multiplexed.mode = Mode::SimultaneousMultiplexed;
    let err = check_before_capture(&calibration, &multiplexed).unwrap_err();
    assert!(
        matches!(err, ScanError::WaterNeedsSequential { .. }),
        "{err}"
    );
    for sigma in [f64::NAN, -1.0, 1e6] {
        let mut bad = config.clone();
        bad.medium = Medium::Water(WaterScan {
            turbidity: None,
            restorer: Restorer::Classical,
            psf_sigma_px: sigma,
            edge_margin_sigmas: underwater::EDGE_MARGIN_SIGMAS,
        });
        let err = check_before_capture(&calibration, &bad).unwrap_err();
        assert!(matches!(err, ScanError::Restore(_)), "{sigma}: {err}");
    }
    // Without restoration the PSF is not used.
    let mut unrestored = config.clone();
    unrestored.medium = Medium::Water(WaterScan {
        turbidity: None,
        restorer: Restorer::None,
        psf_sigma_px: f64::NAN,
        edge_margin_sigmas: underwater::EDGE_MARGIN_SIGMAS,
    });
    check_before_capture(&calibration, &unrestored).unwrap();
}
