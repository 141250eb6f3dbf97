//! File formats at the edges: images in, point clouds and arrays out.
//!
//! Every writer goes through [`write_atomically`], so a failed write never leaves a
//! partial output file behind and never replaces anything but a regular file;
//! each command lists its files in an [`outputs::OutputSet`], which clears an
//! earlier run's before any device is touched and discards its own when it fails.

pub mod cloud_render;
pub mod images;
pub mod npy;
pub mod outputs;
pub mod picture;
pub mod ply;
pub mod ply_read;
pub mod report;
pub mod report_html;

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes a file through a temporary sibling, then renames it over `path`.
///
/// The temporary lives in the same directory (so the rename cannot cross file
/// systems) and is removed when `write` fails. A `path` that is a symlink, a
/// device, a folder or anything else but a regular file is refused, not
/// replaced (a rename would swap the link or the device node for a file).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    check_replaceable(path)?;
    let tmp = temp_sibling(path);
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        // Best effort: the temp file may not exist if creation failed.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Ok when `path` does not exist or is a regular file; an error of kind
/// `AlreadyExists` naming what it is otherwise.
pub fn check_replaceable(path: &Path) -> std::io::Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_file() => Ok(()),
        Ok(m) => Err(std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            format!(
                "{} is {}, not a regular file: refusing to replace it",
                path.display(),
                file_kind(&m.file_type())
            ),
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e),
    }
}

/// "a symlink", "a folder", "a device" ... for an error message.
fn file_kind(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_fifo() {
            return "a pipe";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_symlink() {
        "a symlink"
    } else if t.is_dir() {
        "a folder"
    } else {
        "not a regular file"
    }
}

fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".to_owned());
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("slscan-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("x.bin");
        let err = write_atomically(&path, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("boom"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        write_atomically(&path, |w| w.write_all(b"whole")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"whole");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn links_folders_and_devices_are_refused_not_replaced() {
        let dir = std::env::temp_dir().join(format!("slscan-nonreg-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("target.txt"), b"keep").unwrap();
        std::os::unix::fs::symlink(dir.join("target.txt"), dir.join("link.ply")).unwrap();
        for (path, kind) in [
            (dir.join("link.ply"), "a symlink"),
            (dir.join("sub"), "a folder"),
            (PathBuf::from("/dev/null"), "a device"),
        ] {
            let err = write_atomically(&path, |w| w.write_all(b"new")).unwrap_err();
            assert_eq!(err.kind(), std::io::ErrorKind::AlreadyExists);
            assert!(err.to_string().contains(kind), "{err}");
        }
        // The link is still a link, its target untouched, no temporary left.
        assert!(std::fs::symlink_metadata(dir.join("link.ply"))
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(dir.join("target.txt")).unwrap(), b"keep");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 3);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
