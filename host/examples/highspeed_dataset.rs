//! Training data for the high-speed decoder's zero-order and crosstalk
//! removal network (ZOCR-Net, issue 17, seed 001), in the scan's own
//! geometry: `spheres`' single head (640x480 colour camera, 1280x800 DMD),
//! random static scenes of `hil-sim dataset`'s placement, seed 001's 24
//! binary patterns at 5 kHz in one 4.8 ms exposure
//! ([`slscan::sim::high_speed_samples`]).
//!
//! ```text
//! cargo run --release -p slscan --example highspeed_dataset -- OUT COUNT SEED
//! ```
//!
//! writes `OUT/sample_NNNN.npy` (float32, 2-D `[9 H, W]`: the exposure's R,
//! G, B planes as the camera takes them; each LED band's noise-free AC
//! without crosstalk; each band's zero order; camera full scale) and
//! `OUT/manifest.json`. The held-out scenes of `highspeed_eval` are stream
//! 9001; train on another.

use std::path::PathBuf;

use rayon::prelude::*;
use slscan::highspeed::zocr::set_periods;
use slscan::highspeed::PatternSet;
use slscan::io::npy::encode_npy_f32_rows;
use slscan::sim::high_speed_samples::random_high_speed_sample;
use slscan::sim::twin::Detail;

const CAMERA: (u32, u32) = (640, 480);
const DMD: (u32, u32) = (1280, 800);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, count, seed] = args.as_slice() else {
        return Err("usage: highspeed_dataset OUT COUNT SEED".into());
    };
    let out = PathBuf::from(out);
    let count: usize = count.parse()?;
    let seed: u64 = seed.parse()?;
    if seed == 9001 {
        return Err("stream 9001 is highspeed_eval's held-out set: train on another".into());
    }
    std::fs::create_dir_all(&out)?;
    let set = PatternSet::seed001(DMD)?;
    let detail = Detail {
        camera: CAMERA,
        projector: DMD,
    };
    let started = std::time::Instant::now();
    let files: Vec<String> = (0..count)
        .into_par_iter()
        .map(|i| -> Result<String, String> {
            let s = random_high_speed_sample(&set, &detail, seed, i as u64)
                .map_err(|e| e.to_string())?;
            let data: Vec<f32> = s
                .channels
                .iter()
                .map(|r| &r.data[..])
                .chain(s.ac.iter().map(|v| &v[..]))
                .chain(s.dc.iter().map(|v| &v[..]))
                .flatten()
                .copied()
                .collect();
            let (w, h) = (CAMERA.0 as usize, CAMERA.1 as usize);
            let file = format!("sample_{i:04}.npy");
            std::fs::write(out.join(&file), encode_npy_f32_rows(w, 9 * h, &data))
                .map_err(|e| e.to_string())?;
            Ok(file)
        })
        .collect::<Result<_, String>>()?;
    let periods = set_periods(&set);
    let manifest = serde_json::json!({
        "kind": "highspeed-zocr",
        "seed": seed,
        "count": count,
        "width": CAMERA.0,
        "height": CAMERA.1,
        "dmd": [DMD.0, DMD.1],
        "periods_px": periods,
        "layout": "float32 [9 H, W]: camera R, G, B (noisy, crosstalk, 8-bit); per LED band the noise-free AC (sum of its 8 patterns' B cos phi, no crosstalk); per band the zero order (patterns' mean + ambient); camera full scale",
        "samples": files,
    });
    std::fs::write(
        out.join("manifest.json"),
        serde_json::to_string_pretty(&manifest)?,
    )?;
    eprintln!(
        "{count} samples in {:.1} s -> {}",
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(())
}
