//! `slscan devices list`: the DMD controllers on the USB bus (TI DLPC350 /
//! DLPC900, with their firmware versions), found through hidapi (cargo
//! feature `hid`), and the GenICam cameras (GigE Vision, USB3 Vision, with
//! their firmware versions), found through Aravis (cargo feature `genicam`).

/// Options of `slscan devices`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// List the DMD controllers and cameras found, with firmware versions.
    List,
}

/// Runs `slscan devices`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::List => {
            if !cfg!(feature = "hid") && !cfg!(feature = "genicam") {
                anyhow::bail!(
                    "devices list needs USB HID or Aravis: this slscan was built with neither \
                     (cargo build --release -p slscan --features hid,genicam)"
                );
            }
            list_dmds()?;
            list_cameras();
            Ok(())
        }
    }
}

#[cfg(feature = "hid")]
fn list_dmds() -> anyhow::Result<()> {
    use anyhow::Context;
    use slscan::rig::dlpc::hid::{list, HidapiLink};
    use slscan::rig::dlpc::{DlpcHead, DriverConfig};
    let found = list().context("listing USB HID devices")?;
    if found.is_empty() {
        println!("no DLPC350 / DLPC900 found");
    }
    for f in found {
        let serial = f.serial.as_deref().unwrap_or("-");
        let version = HidapiLink::open(f.controller, f.serial.as_deref())
            .map_err(anyhow::Error::from)
            .and_then(|link| {
                let mut head = DlpcHead::new(link, f.controller, DriverConfig::new(0));
                Ok(head.version()?)
            });
        match version {
            Ok(v) => println!(
                "dmd {}:{serial} interface {} firmware {}.{}.{}",
                f.controller.name().to_lowercase(),
                f.interface,
                v.app >> 24,
                (v.app >> 16) & 0xFF,
                v.app & 0xFFFF
            ),
            Err(e) => println!(
                "dmd {}:{serial} interface {} (version not read: {e:#})",
                f.controller.name().to_lowercase(),
                f.interface
            ),
        }
    }
    Ok(())
}

#[cfg(not(feature = "hid"))]
fn list_dmds() -> anyhow::Result<()> {
    println!("dmd controllers: not searched (this slscan was built without the `hid` feature)");
    Ok(())
}

#[cfg(feature = "genicam")]
fn list_cameras() {
    use slscan::rig::genicam::aravis_camera::{describe, list_cameras};
    let found = list_cameras();
    if found.is_empty() {
        println!("no GenICam camera found");
    }
    for c in found {
        let firmware = describe(&c.id)
            .map(|f| format!("firmware {f}"))
            .unwrap_or_else(|e| format!("(firmware not read: {e})"));
        println!(
            "camera genicam:{} {} {} {} at {} {firmware}",
            c.id, c.vendor, c.model, c.protocol, c.address
        );
    }
}

#[cfg(not(feature = "genicam"))]
fn list_cameras() {
    println!("cameras: not searched (this slscan was built without the `genicam` feature)");
}
