//! `slscan devices list`: the DMD controllers on the USB bus (TI DLPC350 /
//! DLPC900, with their firmware versions), found through hidapi (cargo
//! feature `hid`). Cameras are not listed yet: no GenICam back end.

/// Options of `slscan devices`.
#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// List the DMD controllers found, with firmware versions.
    List,
}

/// Runs `slscan devices`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.command {
        Command::List => list(),
    }
}

#[cfg(feature = "hid")]
fn list() -> anyhow::Result<()> {
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
    println!("cameras: not listed (no GenICam back end yet)");
    Ok(())
}

#[cfg(not(feature = "hid"))]
fn list() -> anyhow::Result<()> {
    anyhow::bail!(
        "devices list needs USB HID: this slscan was built without the `hid` feature \
         (cargo build --release -p slscan --features hid)"
    )
}
