//! `slscan patterns`: write a pattern set as PNG files.

use std::path::PathBuf;

use anyhow::Context;
use clap::ValueEnum;
use slscan::io::images::{save_gray_png, save_rgb_png};
use slscan::patterns::binary::{binarize, pack_bit_planes, Binarize};
use slscan::patterns::gray_code::{gray_code_bits, GrayAxis};
use slscan::patterns::tfc::{tfc_channel_frames, tfc_patterns, TfcSpec};
use slscan::patterns::{multi_frequency_set, FringeAxis, FringeSpec};
use slscan::raster::Raster;

/// Which family of patterns.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Kind {
    /// N-step sinusoidal fringes for each `--periods` entry (period-major).
    Fringes,
    /// Gray codes of `--block` px, plus the `--block - 1` one-pixel shifted sets (pixel-shift fine matching).
    Gray,
    /// The 24 binary patterns of the high-speed colour mode: 8 fringe directions x 3 frequencies on R, G, B.
    Tfc,
}

/// How to make 1-bit patterns for DMD binary mode.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Bits {
    /// Keep 8-bit grey.
    Grey,
    /// Floyd-Steinberg error diffusion.
    Diffusion,
    /// Threshold at 0.5 (binary defocusing).
    Threshold,
}

/// Options of `slscan patterns`.
#[derive(clap::Args)]
pub struct Args {
    /// Pattern family.
    #[arg(long, value_enum, default_value = "fringes")]
    kind: Kind,
    /// Projector width, pixels.
    #[arg(long, default_value_t = 912)]
    width: u32,
    /// Projector height, pixels.
    #[arg(long, default_value_t = 1140)]
    height: u32,
    /// Fringe periods, pixels, comma separated (fringes).
    #[arg(long, value_delimiter = ',', default_values_t = [100.0, 110.0, 120.0])]
    periods: Vec<f64>,
    /// Phase steps N (fringes).
    #[arg(long, default_value_t = 4)]
    steps: usize,
    /// Phase grows along x (columns) or y (rows).
    #[arg(long, value_enum, default_value = "x")]
    axis: AxisArg,
    /// Gray block size, pixels (gray).
    #[arg(long, default_value_t = 4)]
    block: u32,
    /// 1-bit conversion.
    #[arg(long, value_enum, default_value = "grey")]
    bits: Bits,
    /// With 1-bit patterns, also pack them 24 per RGB image as DLPC350 bit planes.
    #[arg(long)]
    pack: bool,
    /// Output folder (created).
    #[arg(long)]
    out: PathBuf,
}

/// Axis option.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum AxisArg {
    /// Columns.
    X,
    /// Rows.
    Y,
}

/// Runs `slscan patterns`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.width > 0 && args.height > 0,
        "projector size {}x{} must be positive",
        args.width,
        args.height
    );
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let axis = match args.axis {
        AxisArg::X => FringeAxis::X,
        AxisArg::Y => FringeAxis::Y,
    };
    let grey: Vec<Raster<f32>> = match args.kind {
        Kind::Fringes => {
            anyhow::ensure!(
                args.steps >= 3,
                "--steps must be at least 3, got {}",
                args.steps
            );
            anyhow::ensure!(
                args.periods.iter().all(|p| p.is_finite() && *p > 0.0),
                "periods must be positive: {:?}",
                args.periods
            );
            let spec = FringeSpec::full_contrast(args.width, args.height, 1.0, args.steps, axis);
            multi_frequency_set(&spec, &args.periods)
        }
        Kind::Gray => {
            anyhow::ensure!(args.block > 0, "--block must be positive");
            let g = match axis {
                FringeAxis::X => GrayAxis::Columns,
                FringeAxis::Y => GrayAxis::Rows,
            };
            (0..args.block)
                .flat_map(|shift| gray_code_bits(args.width, args.height, args.block, shift, g))
                .collect()
        }
        Kind::Tfc => {
            let pats = tfc_patterns(&TfcSpec::seed001(), args.width, args.height);
            if matches!(args.bits, Bits::Grey) {
                clear_earlier_patterns(&args.out)?;
                for (i, p) in pats.iter().enumerate() {
                    let rgb = Raster {
                        width: p.width,
                        height: p.height,
                        data: p
                            .data
                            .iter()
                            .map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
                            .collect(),
                    };
                    save_rgb_png(&args.out.join(format!("tfc_rgb_{i:03}.png")), &rgb)?;
                }
                println!(
                    "wrote {} RGB patterns to {}",
                    pats.len(),
                    args.out.display()
                );
                return Ok(());
            }
            tfc_channel_frames(&pats)
        }
    };
    clear_earlier_patterns(&args.out)?;
    let method = match args.bits {
        Bits::Grey => None,
        Bits::Diffusion => Some(Binarize::ErrorDiffusion),
        Bits::Threshold => Some(Binarize::Threshold),
    };
    let Some(method) = method else {
        for (i, f) in grey.iter().enumerate() {
            save_gray_png(&args.out.join(format!("pattern_{i:03}.png")), f, false)?;
        }
        println!("wrote {} patterns to {}", grey.len(), args.out.display());
        return Ok(());
    };
    let planes: Vec<Raster<bool>> = grey.iter().map(|g| binarize(g, method)).collect();
    if args.pack {
        let packed = pack_bit_planes(&planes)?;
        for (i, p) in packed.iter().enumerate() {
            save_rgb_png(&args.out.join(format!("bitplanes_{i:03}.png")), p)?;
        }
        println!(
            "wrote {} patterns as {} bit-plane images to {}",
            planes.len(),
            packed.len(),
            args.out.display()
        );
    } else {
        for (i, p) in planes.iter().enumerate() {
            let f = Raster {
                width: p.width,
                height: p.height,
                data: p.data.iter().map(|&b| f32::from(u8::from(b))).collect(),
            };
            save_gray_png(&args.out.join(format!("pattern_{i:03}.png")), &f, false)?;
        }
        println!(
            "wrote {} 1-bit patterns to {}",
            planes.len(),
            args.out.display()
        );
    }
    Ok(())
}

/// File-name prefixes of the pattern files this command writes.
const PATTERN_PREFIXES: [&str; 3] = ["pattern_", "bitplanes_", "tfc_rgb_"];

/// Removes an earlier run's pattern files from `dir` (`pattern_NNN.png`,
/// `bitplanes_NNN.png`, `tfc_rgb_NNN.png`; nothing else), so a smaller set
/// does not leave the old set's tail for a DMD tool to load with it.
fn clear_earlier_patterns(dir: &std::path::Path) -> anyhow::Result<()> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    let paths = entries
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_str().is_some_and(is_pattern_file))
        .map(|e| e.path());
    slscan::io::outputs::OutputSet::new(paths).clear()?;
    Ok(())
}

/// A name this command writes: a prefix, the index in at least three
/// digits (`{i:03}` gives four from pattern 1000 on), `.png`.
fn is_pattern_file(name: &str) -> bool {
    PATTERN_PREFIXES.iter().any(|prefix| {
        name.strip_prefix(prefix)
            .and_then(|rest| rest.strip_suffix(".png"))
            .is_some_and(|n| n.len() >= 3 && n.bytes().all(|b| b.is_ascii_digit()))
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_index_this_command_writes_is_its_own_and_nothing_else() {
        for name in [
            "pattern_000.png",
            "pattern_1000.png",
            "bitplanes_012.png",
            "tfc_rgb_023.png",
        ] {
            assert!(super::is_pattern_file(name), "{name}");
        }
        for name in [
            "pattern_01.png",
            "pattern_abc.png",
            "notes.png",
            "pattern_000.tif",
        ] {
            assert!(!super::is_pattern_file(name), "{name}");
        }
    }
}
