//! DMD pattern sets on hardware, handed over as files.
//!
//! PLACEHOLDER: no DMD driver uploads patterns. The DLPC900 / DLPC350 take
//! their pattern table over USB HID or I2C with a vendor protocol this
//! project has no driver for. Instead, each head's sequence is written as a
//! numbered PNG set, `PATTERNS/<head>/pattern_000.png`, `pattern_001.png`,
//! ... (trigger order; 8-bit grey, a binary pattern as 0/255), for the DMD
//! vendor's GUI (TI's DLP LightCrafter GUI) to load into the pattern table,
//! one pattern per trigger. Two ways to use it:
//!
//! - [`PatternDelivery::Write`]: the set is written and the scan goes on at
//!   once, with a loud PLACEHOLDER warning: right only if the DMD already
//!   holds this very set (loaded from an earlier run's files) or a tool
//!   watching the folder loads it.
//! - [`PatternDelivery::Preloaded`]: the user loaded the set into the DMD
//!   from this folder before the scan; slscan checks the folder holds
//!   exactly the patterns the scan needs (count, size and 8-bit values), so a
//!   set left from another mode or period choice is caught, not scanned.

use std::path::{Path, PathBuf};

use super::{Led, Projector, RigError, WHITE};
use crate::calibration::RigCalibration;
use crate::io::images::{list_images, load_gray, save_gray_png, ImageError};
use crate::raster::Raster;

/// How patterns reach the DMD.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatternDelivery {
    /// Write the set into the folder (PLACEHOLDER: nothing uploads it).
    Write,
    /// The DMD holds the set already; check the folder's copy matches.
    Preloaded,
}

/// One head's projector.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FolderProjectorHead {
    /// Head name (the subfolder's name), e.g. `A`.
    pub name: String,
    /// DMD size (width, height), pixels.
    pub dmd_size_px: (u32, u32),
}

impl FolderProjectorHead {
    /// Each calibrated head's projector: its name and DMD size.
    pub fn of_rig(calibration: &RigCalibration) -> Vec<FolderProjectorHead> {
        calibration
            .heads
            .iter()
            .map(|h| FolderProjectorHead {
                name: h.name.clone(),
                dmd_size_px: (h.projector.width_px, h.projector.height_px),
            })
            .collect()
    }
}

/// Pattern sets as PNG files for the DMD vendor's GUI; see the module doc.
#[derive(Debug)]
pub struct FolderProjector {
    root: PathBuf,
    heads: Vec<FolderProjectorHead>,
    delivery: PatternDelivery,
}

impl FolderProjector {
    /// Patterns of head `h` go to (or are checked in) `root/<name of h>/`.
    pub fn new(root: PathBuf, heads: Vec<FolderProjectorHead>, delivery: PatternDelivery) -> Self {
        FolderProjector {
            root,
            heads,
            delivery,
        }
    }

    /// The folder head `head`'s patterns live in.
    pub fn head_dir(&self, head: usize) -> Result<PathBuf, RigError> {
        Ok(self.root.join(&self.head(head)?.name))
    }

    fn head(&self, head: usize) -> Result<&FolderProjectorHead, RigError> {
        self.heads.get(head).ok_or(RigError::NoSuchHead {
            head,
            heads: self.heads.len(),
        })
    }

    /// Writes the set (as [`Self::write`]) and, for a coloured one, the LEDs
    /// of each pattern as `pattern_leds.json` (`[[r, g, b], ...]` in trigger
    /// order) for the GUI's pattern LUT; a white set leaves no such file.
    fn write_with_leds(
        &self,
        head: usize,
        dir: &Path,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<(), RigError> {
        self.write(head, dir, patterns)?;
        let path = dir.join(LED_FILE);
        let folder = |source| RigError::Folder {
            path: path.clone(),
            source,
        };
        if leds.iter().all(|l| *l == WHITE) {
            return match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(folder(e)),
                _ => Ok(()),
            };
        }
        let json = serde_json::to_vec(leds).map_err(|e| folder(std::io::Error::other(e)))?;
        crate::io::write_atomically(&path, |w| w.write_all(&json)).map_err(folder)
    }

    fn write(&self, head: usize, dir: &Path, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        let io = |path: &Path| {
            let path = path.to_owned();
            move |source| RigError::Folder { path, source }
        };
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        // Earlier sets may be longer: a GUI loading the folder must not
        // pick up their tail.
        for old in std::fs::read_dir(dir).map_err(io(dir))? {
            let old = old.map_err(io(dir))?.path();
            if is_pattern_file(&old) {
                std::fs::remove_file(&old).map_err(io(&old))?;
            }
        }
        for (k, p) in patterns.iter().enumerate() {
            let path = dir.join(pattern_file_name(k));
            save_gray_png(&path, p, false).map_err(|e| image_to_rig(head, e))?;
        }
        let warning = format!(
            "PLACEHOLDER: no DMD driver uploads patterns: head {} needs its {} patterns in {} \
             loaded into the DMD's pattern table (one per trigger, in file order) by the DMD \
             vendor's GUI; the scan goes on assuming the DMD shows them",
            self.heads[head].name,
            patterns.len(),
            dir.display()
        );
        // Once, in the log (a library does not print).
        tracing::warn!("{warning}");
        Ok(())
    }

    fn check_preloaded(
        &self,
        head: usize,
        dir: &Path,
        patterns: &[Raster<f32>],
    ) -> Result<(), RigError> {
        let files: Vec<PathBuf> = list_images(dir)
            .map_err(|e| image_to_rig(head, e))?
            .into_iter()
            .filter(|p| is_pattern_file(p))
            .collect();
        let mismatch = |found| RigError::PatternsPreloaded {
            head,
            path: dir.to_owned(),
            expected: patterns.len(),
            found,
        };
        if files.len() != patterns.len() {
            return Err(mismatch(files.len()));
        }
        for (k, want) in patterns.iter().enumerate() {
            let path = dir.join(pattern_file_name(k));
            let got = load_gray(&path).map_err(|e| image_to_rig(head, e))?.image;
            if got.size() != want.size() {
                return Err(RigError::PatternSize {
                    head,
                    expected: self.heads[head].dmd_size_px,
                    got: got.size(),
                });
            }
            let same = got
                .data
                .iter()
                .zip(&want.data)
                .all(|(g, w)| (g - w.clamp(0.0, 1.0)).abs() <= 0.6 / 255.0);
            if !same {
                // Counted up to the first pattern that differs.
                return Err(mismatch(k));
            }
        }
        tracing::info!(head = self.heads[head].name, patterns = files.len(), folder = %dir.display(), "pre-loaded DMD patterns match the scan");
        Ok(())
    }
}

/// The LEDs of a coloured set, beside its patterns.
pub const LED_FILE: &str = "pattern_leds.json";

/// `pattern_007.png` for trigger 7.
pub fn pattern_file_name(k: usize) -> String {
    format!("pattern_{k:03}.png")
}

fn is_pattern_file(path: &Path) -> bool {
    path.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with("pattern_") && n.ends_with(".png"))
}

fn image_to_rig(head: usize, source: ImageError) -> RigError {
    RigError::PatternImage { head, source }
}

impl Projector for FolderProjector {
    fn dmd_size_px(&self, head: usize) -> Result<(u32, u32), RigError> {
        Ok(self.head(head)?.dmd_size_px)
    }

    fn load_sequence(&mut self, head: usize, patterns: &[Raster<f32>]) -> Result<(), RigError> {
        self.load_coloured_sequence(head, patterns, &vec![WHITE; patterns.len()])
    }

    fn load_coloured_sequence(
        &mut self,
        head: usize,
        patterns: &[Raster<f32>],
        leds: &[Led],
    ) -> Result<(), RigError> {
        super::check_sequence(head, self.dmd_size_px(head)?, patterns, leds)?;
        let white = leds.iter().all(|l| *l == WHITE);
        if !white && self.delivery == PatternDelivery::Preloaded {
            // A pre-loaded set's LEDs cannot be checked from its PNGs.
            return Err(RigError::NoLedControl { head });
        }
        let dir = self.head_dir(head)?;
        match self.delivery {
            PatternDelivery::Write => self.write_with_leds(head, &dir, patterns, leds),
            PatternDelivery::Preloaded => self.check_preloaded(head, &dir, patterns),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn projector(root: &Path, delivery: PatternDelivery) -> FolderProjector {
        FolderProjector::new(
            root.to_owned(),
            vec![FolderProjectorHead {
                name: "A".into(),
                dmd_size_px: (8, 2),
            }],
            delivery,
        )
    }

    fn set(n: usize) -> Vec<Raster<f32>> {
        (0..n)
            .map(|k| Raster::from_fn(8, 2, |x, _| ((x + k) % 8) as f32 / 7.0))
            .collect()
    }

    #[test]
    fn a_written_set_reads_back_and_passes_the_preloaded_check() {
        let root = std::env::temp_dir().join(format!("slscan-folder-dmd-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        projector(&root, PatternDelivery::Write)
            .load_sequence(0, &set(12))
            .unwrap();
        // A shorter set replaces the longer one whole.
        projector(&root, PatternDelivery::Write)
            .load_sequence(0, &set(3))
            .unwrap();
        let dir = root.join("A");
        let back = load_gray(&dir.join(pattern_file_name(2))).unwrap().image;
        assert!(back
            .data
            .iter()
            .zip(&set(3)[2].data)
            .all(|(a, b)| (a - b).abs() <= 0.5 / 255.0));
        let mut pre = projector(&root, PatternDelivery::Preloaded);
        pre.load_sequence(0, &set(3)).unwrap();
        let err = pre.load_sequence(0, &set(4)).unwrap_err();
        assert!(
            matches!(
                err,
                RigError::PatternsPreloaded {
                    expected: 4,
                    found: 3,
                    ..
                }
            ),
            "{err}"
        );
        // Same count, other content: pattern 0 differs.
        let mut other = set(3);
        other[0].data[0] = 1.0 - other[0].data[0];
        let err = pre.load_sequence(0, &other).unwrap_err();
        assert!(
            matches!(err, RigError::PatternsPreloaded { found: 0, .. }),
            "{err}"
        );
        let err = pre
            .load_sequence(0, &[Raster::filled(4, 2, 0.0)])
            .unwrap_err();
        assert!(matches!(err, RigError::PatternSize { .. }), "{err}");
        std::fs::remove_dir_all(&root).unwrap();
    }

    #[test]
    fn a_coloured_set_writes_its_leds_and_a_white_one_removes_them() {
        let root = std::env::temp_dir().join(format!("slscan-folder-leds-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let leds = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut p = projector(&root, PatternDelivery::Write);
        p.load_coloured_sequence(0, &set(3), &leds).unwrap();
        let file = root.join("A").join(LED_FILE);
        let back: Vec<[f32; 3]> = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
        assert_eq!(back, leds);
        // LEDs that do not pair with the patterns, and colour for a
        // pre-loaded set, are refused.
        assert!(matches!(
            p.load_coloured_sequence(0, &set(2), &leds),
            Err(RigError::NoLedControl { head: 0 })
        ));
        assert!(matches!(
            projector(&root, PatternDelivery::Preloaded).load_coloured_sequence(0, &set(3), &leds),
            Err(RigError::NoLedControl { head: 0 })
        ));
        p.load_sequence(0, &set(3)).unwrap();
        assert!(!file.exists());
        std::fs::remove_dir_all(&root).unwrap();
    }
}
