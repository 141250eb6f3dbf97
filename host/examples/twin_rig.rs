//! Writes a built-in twin scene's TRUE rig calibration as a rig file,
//! optionally with one device deliberately off, to see what a scan with a
//! wrong calibration reports:
//!
//! ```text
//! cargo run --release -p slscan --example twin_rig -- SCENE OUT.json [HEAD DEVICE FX_SCALE]
//! cargo run --release -p slscan --example twin_rig -- large-part out/rig_fx05.json A camera 1.005
//! ```

use std::path::PathBuf;

use anyhow::Context;
use slscan::calibration::write_rig;
use slscan::sim::twin::Detail;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [scene, out, rest @ ..] = args.as_slice() else {
        anyhow::bail!("usage: twin_rig SCENE OUT.json [HEAD camera|projector FX_SCALE]");
    };
    let mut rig = slscan::sim::truth::scene_calibration(scene, &Detail::default())?;
    if let [head, device, scale] = rest {
        let scale: f64 = scale.parse().context("FX_SCALE")?;
        let h = rig
            .heads
            .iter_mut()
            .find(|h| &h.name == head)
            .with_context(|| format!("scene {scene} has no head {head}"))?;
        let model = match device.as_str() {
            "camera" => &mut h.camera,
            "projector" => &mut h.projector,
            other => anyhow::bail!("device {other:?}: camera or projector"),
        };
        model.intrinsics.fx *= scale;
        eprintln!("head {head} {device} fx scaled by {scale} (deliberately wrong)");
    }
    write_rig(&PathBuf::from(out), &rig)?;
    println!("wrote {out}");
    Ok(())
}
