//! `slscan calibration import | export`: OpenCV calibration files in and out.
//!
//! `import --opencv FILE --out rig.json` reads a `cv::FileStorage` YAML or XML file
//! (projector-camera `M1 D1 M4 D4 Rlp Tlp`, stereo `M1 D1 M2 D2 R T` or
//! `R1 R2 P1 P2 Q`), checks its conventions (`slscan::calibration::opencv::import`)
//! and writes our rig file; `export --rig rig.json --out FILE.yml|.yaml|.xml` writes one
//! head of a rig as an OpenCV file (`--format yaml|xml` overrides the extension). Both check every option and input before writing,
//! and write atomically: a failure leaves no output, old or new, half-written.

use std::path::PathBuf;

use anyhow::Context;
use slscan::calibration::opencv::{
    read_opencv, storage, write_opencv, Format, ImportOptions, Imported, LengthUnit, SecondDevice,
};
use slscan::calibration::{read_rig, write_rig};

use super::calibration_print::print_device;
use super::parse::parse_size;
use super::transcript::say;

/// Options of `slscan calibration`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// OpenCV FileStorage file (YAML/XML) -> rig file (JSON).
    Import(ImportArgs),
    /// Rig file (JSON) -> OpenCV FileStorage file (YAML/XML, by extension).
    Export(ExportArgs),
}

/// Options of `slscan calibration import`.
#[derive(clap::Args)]
struct ImportArgs {
    /// The OpenCV calibration file (`.yml`, `.yaml` or `.xml`, told apart by content).
    #[arg(long, value_name = "FILE")]
    opencv: PathBuf,
    /// The rig file to write (JSON).
    #[arg(long, short, value_name = "FILE")]
    out: PathBuf,
    /// Length unit of the file's translations (T, Tlp, P2): mm or m.
    #[arg(long, default_value = "mm", value_name = "mm|m")]
    unit: LengthUnit,
    /// Camera image size, when the file does not give it.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    camera_size: Option<(u32, u32)>,
    /// Projector DMD size, when the file does not give it.
    #[arg(long, value_name = "WxH", value_parser = parse_size)]
    projector_size: Option<(u32, u32)>,
    /// Name of the head in the rig file.
    #[arg(long, default_value = "A")]
    name: String,
    /// What device 2 of an `M1 D1 M2 D2 R T` file is: camera (a stereo head) or projector.
    #[arg(long, value_name = "projector|camera")]
    second: Option<SecondDevice>,
    /// The file's R, T map device 2 into device 1: invert them on import.
    #[arg(long)]
    invert_extrinsics: bool,
}

/// Options of `slscan calibration export`.
#[derive(clap::Args)]
struct ExportArgs {
    /// The rig file to read (JSON).
    #[arg(long, value_name = "FILE")]
    rig: PathBuf,
    /// The OpenCV file to write: `.yml` / `.yaml` (YAML) or `.xml` (XML).
    #[arg(long, short, value_name = "FILE")]
    out: PathBuf,
    /// yaml or xml, whatever the extension of --out says.
    #[arg(long, value_name = "yaml|xml", value_parser = parse_format)]
    format: Option<Format>,
    /// Length unit of the written translations: mm or m.
    #[arg(long, default_value = "mm", value_name = "mm|m")]
    unit: LengthUnit,
    /// Which head to write, when the rig has several.
    #[arg(long, value_name = "NAME")]
    head: Option<String>,
}

/// Runs `slscan calibration ...`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::Import(a) => import(a),
        Command::Export(a) => export(a),
    }
}

fn import(a: ImportArgs) -> anyhow::Result<()> {
    slscan::io::check_replaceable(&a.out).with_context(|| format!("--out {}", a.out.display()))?;
    let options = ImportOptions {
        unit: a.unit,
        camera_size_px: a.camera_size,
        projector_size_px: a.projector_size,
        name: a.name,
        second: a.second.unwrap_or_default(),
        invert_extrinsics: a.invert_extrinsics,
    };
    let imported = read_opencv(&a.opencv, &options)
        .with_context(|| format!("importing {}", a.opencv.display()))?;
    match &imported {
        Imported::Head(h) => {
            say!("projector-camera head {:?}", h.name);
            print_device("camera", &h.camera);
            print_device("projector", &h.projector);
            print_baseline("camera->projector", &h.projector);
        }
        Imported::Stereo(h) => {
            say!("stereo head {:?}", h.name);
            print_device("left camera", &h.left);
            print_device("right camera", &h.right);
            print_baseline("left->right", &h.right);
        }
        Imported::Camera(_) => {}
    }
    let rig = imported
        .into_rig()
        .with_context(|| format!("importing {}", a.opencv.display()))?;
    write_rig(&a.out, &rig).with_context(|| format!("writing {}", a.out.display()))?;
    say!("wrote {}", a.out.display());
    Ok(())
}

fn print_baseline(what: &str, second: &slscan::calibration::PinholeModel) {
    let c = second.centre_m().coords * 1e3;
    say!(
        "{what}: device 2 at ({:.3}, {:.3}, {:.3}) mm, baseline {:.3} mm",
        c.x,
        c.y,
        c.z,
        c.norm()
    );
}

fn parse_format(s: &str) -> Result<Format, String> {
    match s {
        "yaml" | "yml" => Ok(Format::Yaml),
        "xml" => Ok(Format::Xml),
        _ => Err(format!("format {s:?}: expected yaml or xml")),
    }
}

fn export(a: ExportArgs) -> anyhow::Result<()> {
    if a.format.is_none() && storage::format_of(&a.out).is_none() {
        anyhow::bail!(
            "--out {}: name it .yml, .yaml or .xml, or give --format yaml|xml",
            a.out.display()
        );
    }
    slscan::io::check_replaceable(&a.out).with_context(|| format!("--out {}", a.out.display()))?;
    let rig = read_rig(&a.rig).with_context(|| format!("reading {}", a.rig.display()))?;
    write_opencv(&a.out, &rig, a.head.as_deref(), a.unit, a.format)
        .with_context(|| format!("writing {}", a.out.display()))?;
    say!("wrote {}", a.out.display());
    Ok(())
}
