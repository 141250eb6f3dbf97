//! `hil-sim render`: pictures of a built-in scene for a person to look at:
//! per camera the fringe image, a flood image, depth, absolute phase of
//! each projector in both directions, normals and the truth masks.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use hil_sim::twin::io::{create_dir, write_json, write_npy, write_png, PngDepth};
use hil_sim::twin::scenes::{built_in, Detail};
use hil_sim::twin::{
    render_exposure, BitDepth, Exposure, Frame, Fringe, Medium, Pattern, ProjectorTimeline, Rig,
    Scene, SensorModel, Turbidity, Water,
};
use rand::SeedableRng;

/// Options of `hil-sim render`.
#[derive(clap::Args, Clone)]
pub struct Args {
    /// Built-in scene name (see `hil-sim scenes`), or `all` for every scene, one folder each.
    #[arg(long)]
    scene: String,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
    /// Camera image width, pixels.
    #[arg(long, default_value_t = 640)]
    width: u32,
    /// Camera image height, pixels.
    #[arg(long, default_value_t = 480)]
    height: u32,
    /// Fringe period on the DMD, pixels.
    #[arg(long, default_value_t = 32.0)]
    period_px: f64,
    /// Camera exposure, microseconds.
    #[arg(long, default_value_t = 1000.0)]
    exposure_us: f64,
    /// Put the rig under water at this turbidity (flat ports 30 mm in front of each device).
    #[arg(long)]
    turbidity: Option<Turbidity>,
    /// Use the 8-bit colour sensor (with channel crosstalk) instead of the 12-bit mono one.
    #[arg(long)]
    colour: bool,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Renders the scene and writes the pictures.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.scene == "all" {
        for b in hil_sim::twin::scenes::BUILT_IN {
            let out = args.out.join(b.name);
            run_one(&Args {
                scene: b.name.to_string(),
                out,
                ..args
            })?;
        }
        return Ok(());
    }
    run_one(&args)
}

fn run_one(args: &Args) -> anyhow::Result<()> {
    let detail = Detail {
        camera: (args.width, args.height),
        ..Detail::default()
    };
    let (scene, mut rig) = built_in(&args.scene, &detail)?;
    if let Some(t) = args.turbidity {
        rig.medium = Medium::Water(Water::preset(t, 0.03));
    }
    create_dir(&args.out)?;
    let exposure = Exposure {
        start_s: 0.0,
        end_s: args.exposure_us * 1e-6,
    };
    let sensor = if args.colour {
        SensorModel::colour8()
    } else {
        SensorModel::mono12()
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(args.seed);
    let fringe = Fringe {
        period_px: args.period_px,
        angle_rad: 0.0,
        shift_rad: 0.0,
    };
    let mut summary = Vec::new();
    for (c, cam) in rig.cameras.iter().enumerate() {
        let show = |p: Option<&Fringe>| -> Vec<ProjectorTimeline> {
            rig.projectors
                .iter()
                .map(|pr| {
                    let (w, h) = (pr.model.intrinsics.width, pr.model.intrinsics.height);
                    let pat = match p {
                        Some(f) => Pattern::fringe(w, h, f, BitDepth::Eight),
                        None => Pattern::flat(w, h, 1.0),
                    };
                    ProjectorTimeline::single(Arc::new(pat), exposure.start_s, exposure.end_s)
                })
                .collect()
        };
        let fringes = render_exposure(
            &scene,
            &rig,
            c,
            &show(Some(&fringe)),
            exposure,
            &sensor,
            &mut rng,
        )?;
        let flood = render_exposure(&scene, &rig, c, &show(None), exposure, &sensor, &mut rng)?;
        let prefix = args.out.join(&cam.name);
        write_camera(&prefix, &rig, &fringes, &flood, &fringe)
            .with_context(|| format!("writing {}", cam.name))?;
        summary.push(camera_summary(&cam.name, &fringes));
        tracing::info!(camera = %cam.name, "rendered");
    }
    let doc = serde_json::json!({
        "scene": args.scene,
        "objects": scene_objects(&scene),
        "exposure_us": args.exposure_us,
        "period_px": args.period_px,
        "turbidity": args.turbidity.map(|t| format!("{t:?}")),
        "seed": args.seed,
        "cameras": summary,
        "rig": rig,
    });
    write_json(&args.out.join("render.json"), &doc)?;
    println!(
        "wrote {} camera(s) of `{}` to {}",
        rig.cameras.len(),
        args.scene,
        args.out.display()
    );
    Ok(())
}

fn scene_objects(scene: &Scene) -> Vec<String> {
    scene.objects.iter().map(|o| o.name.clone()).collect()
}

fn camera_summary(name: &str, f: &Frame) -> serde_json::Value {
    let t = &f.truth;
    let d: Vec<f32> = t
        .depth_m()
        .iter()
        .cloned()
        .filter(|d| d.is_finite())
        .collect();
    let count = |m: &[bool]| m.iter().filter(|&&b| b).count();
    serde_json::json!({
        "camera": name,
        "surface_px": d.len(),
        "depth_min_mm": d.iter().cloned().fold(f32::INFINITY, f32::min) * 1e3,
        "depth_max_mm": d.iter().cloned().fold(f32::NEG_INFINITY, f32::max) * 1e3,
        "overlap_px": count(t.overlap()),
        "saturated_px": count(&t.saturated),
        "shadow_px": (0..t.projectors()).map(|p| count(&t.shadow_mask(p))).collect::<Vec<_>>(),
    })
}

fn write_camera(
    prefix: &Path,
    rig: &Rig,
    fringes: &Frame,
    flood: &Frame,
    fringe: &Fringe,
) -> anyhow::Result<()> {
    let t = &fringes.truth;
    let (w, h) = (t.width(), t.height());
    let file = |suffix: &str| PathBuf::from(format!("{}_{suffix}", prefix.display()));
    let img = &fringes.image;
    write_png(
        &file("image.png"),
        w,
        h,
        img.channels,
        &img.data,
        PngDepth::Sixteen,
    )?;
    write_png(
        &file("flood.png"),
        w,
        h,
        flood.image.channels,
        &flood.image.data,
        PngDepth::Sixteen,
    )?;
    // Depth: near = bright, background black.
    let finite: Vec<f32> = t
        .depth_m()
        .iter()
        .cloned()
        .filter(|d| d.is_finite())
        .collect();
    let (lo, hi) = finite
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &d| {
            (a.min(d), b.max(d))
        });
    let depth_img: Vec<f32> = t
        .depth_m()
        .iter()
        .map(|&d| {
            if d.is_finite() {
                0.1 + 0.9 * (hi - d) / (hi - lo).max(1e-9)
            } else {
                0.0
            }
        })
        .collect();
    write_png(&file("depth.png"), w, h, 1, &depth_img, PngDepth::Sixteen)?;
    write_npy(&file("depth_m.npy"), &[h as usize, w as usize], t.depth_m())?;
    let normals: Vec<f32> = t
        .normal()
        .iter()
        .flat_map(|n| n.map(|c| if c.is_finite() { 0.5 + 0.5 * c } else { 0.0 }))
        .collect();
    write_png(&file("normal.png"), w, h, 3, &normals, PngDepth::Eight)?;
    for (p, proj) in rig.projectors.iter().enumerate() {
        for (dir, angle) in [("u", 0.0), ("v", std::f64::consts::FRAC_PI_2)] {
            let f = Fringe {
                angle_rad: angle,
                ..*fringe
            };
            let phase = t.absolute_phase(p, &f);
            let wrapped: Vec<f32> = phase
                .iter()
                .map(|&v| {
                    if v.is_finite() {
                        v.rem_euclid(std::f32::consts::TAU) / std::f32::consts::TAU
                    } else {
                        0.0
                    }
                })
                .collect();
            write_png(
                &file(&format!("phase_{dir}_{}.png", proj.name)),
                w,
                h,
                1,
                &wrapped,
                PngDepth::Eight,
            )?;
            write_npy(
                &file(&format!("phase_{dir}_{}.npy", proj.name)),
                &[h as usize, w as usize],
                &phase,
            )?;
        }
    }
    // Masks: red = shadowed from some projector, green = overlap, blue = saturated, grey = no surface.
    let no_surface = t.no_surface_mask();
    let shadows: Vec<Vec<bool>> = (0..rig.projectors.len())
        .map(|p| t.shadow_mask(p))
        .collect();
    let mask: Vec<f32> = (0..(w * h) as usize)
        .flat_map(|i| {
            if no_surface[i] {
                return [0.3; 3];
            }
            let s = shadows.iter().any(|m| m[i]);
            [
                s as u8 as f32,
                t.overlap()[i] as u8 as f32,
                t.saturated[i] as u8 as f32,
            ]
        })
        .collect();
    write_png(&file("mask.png"), w, h, 3, &mask, PngDepth::Eight)?;
    Ok(())
}
