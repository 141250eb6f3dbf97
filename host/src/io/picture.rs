//! Pictures a person reads without the source: a perceptual colour map
//! (viridis, or grey for camera images), a panel under the image with the
//! title, a colour bar with its range and unit, and a legend that gives each
//! kind of pixel without a value its own colour and share.
//!
//! Viridis holds no grey, red or magenta, so the four marked colours can
//! never be read as a value. Text is the public-domain 8x8 bitmap font
//! (`font8x8`), scaled with the image width.

use crate::raster::Raster;

/// What a pixel of a picture shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelClass {
    /// A value, drawn by the colour map.
    Value,
    /// No fringe light reached it: shadow, or off the object.
    NoFringe,
    /// Masked: lit, but its fringe was not usable (too little modulation,
    /// lit by the other projector in the simultaneous mode).
    Masked,
    /// Lit and modulated, but the fringe-order check refused it.
    Unreliable,
    /// At least one frame at full scale.
    Saturated,
}

impl PixelClass {
    /// The four classes without a value, in legend order.
    pub const MARKED: [PixelClass; 4] = [
        PixelClass::NoFringe,
        PixelClass::Masked,
        PixelClass::Unreliable,
        PixelClass::Saturated,
    ];

    /// The marked colour (`None` for a value).
    pub fn colour(self) -> Option<[u8; 3]> {
        match self {
            PixelClass::Value => None,
            PixelClass::NoFringe => Some([96, 96, 96]),
            PixelClass::Masked => Some([192, 192, 192]),
            PixelClass::Unreliable => Some([255, 0, 255]),
            PixelClass::Saturated => Some([255, 0, 0]),
        }
    }

    /// The legend's words.
    pub fn label(self) -> &'static str {
        match self {
            PixelClass::Value => "value",
            PixelClass::NoFringe => "no fringe (shadow/off object)",
            PixelClass::Masked => "masked",
            PixelClass::Unreliable => "unreliable (order check)",
            PixelClass::Saturated => "saturated",
        }
    }
}

/// How values map to colours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// A stated range (values outside are drawn at its ends; the bar's end
    /// labels say so), where pictures are compared.
    Fixed {
        /// Value at the map's start.
        lo: f64,
        /// Value at the map's end.
        hi: f64,
    },
    /// From the 1st to the 99th percentile of the picture's values.
    Robust,
}

/// The colour map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourMap {
    /// Perceptual, dark blue to yellow.
    Viridis,
    /// Black to white (camera images).
    Grey,
}

impl ColourMap {
    fn at(self, t: f64) -> [u8; 3] {
        let t = t.clamp(0.0, 1.0);
        match self {
            ColourMap::Viridis => {
                let c = colorous::VIRIDIS.eval_continuous(t);
                [c.r, c.g, c.b]
            }
            ColourMap::Grey => {
                let v = (t * 255.0).round() as u8;
                [v, v, v]
            }
        }
    }
}

/// What to draw.
#[derive(Clone, Debug, PartialEq)]
pub struct PictureSpec<'a> {
    /// The title line, e.g. "head A: depth along the camera axis".
    pub title: &'a str,
    /// The unit of the values, e.g. "mm".
    pub unit: &'a str,
    /// The range of the colour map.
    pub range: Range,
    /// The map.
    pub map: ColourMap,
}

/// One legend entry as drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct LegendEntry {
    /// The class.
    pub class: PixelClass,
    /// Pixels of that class.
    pub pixels: usize,
    /// Top-left corner of its swatch in the picture.
    pub swatch_xy: (usize, usize),
}

/// A drawn picture and where its parts are.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// The image: the data on top, the panel below.
    pub image: Raster<[u8; 3]>,
    /// The range the colour map spans (after [`Range::Robust`] is resolved).
    pub lo: f64,
    /// See `lo`.
    pub hi: f64,
    /// Pixel rows of the data (the panel starts below).
    pub data_height: usize,
    /// The legend as drawn.
    pub legend: Vec<LegendEntry>,
}

const PANEL: [u8; 3] = [255, 255, 255];
const INK: [u8; 3] = [0, 0, 0];

/// Draws `values` with `classes` (same size) as `spec` says.
///
/// # Panics
/// If `classes` is not the size of `values`.
pub fn draw(values: &Raster<f32>, classes: &Raster<PixelClass>, spec: &PictureSpec) -> Picture {
    assert_eq!(values.size(), classes.size(), "classes sized as the values");
    let (lo, hi) = resolve_range(values, classes, spec.range);
    let (w, h) = values.size();
    let s = (w / 640).max(1);
    let glyph = 8 * s;
    let margin = 4 * s;
    // Wide enough for the legend's longest line even on a small image.
    let width = w.max(44 * glyph + 2 * margin);
    let legend = Legend::lay_out(classes, width, glyph, margin);
    let legend_lines = legend.lines;
    let panel_h =
        margin + glyph + margin + glyph + s * 2 + glyph + margin + legend_lines * (glyph + margin);
    let mut img = Raster::filled(width, h + panel_h, PANEL);
    let span = if hi > lo { hi - lo } else { 1.0 };
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let c = classes.data[i];
            let v = values.data[i];
            img.data[y * width + x] = match c.colour() {
                Some(marked) => marked,
                None if v.is_finite() => spec.map.at((f64::from(v) - lo) / span),
                None => PixelClass::Masked.colour().unwrap_or(PANEL),
            };
        }
    }
    let mut y = h + margin;
    text(&mut img, margin, y, spec.title, s);
    y += glyph + margin;
    // The colour bar, then its end labels and unit under it.
    let bar_w = (width - 2 * margin).min(320 * s);
    for dy in 0..glyph {
        for dx in 0..bar_w {
            let t = dx as f64 / (bar_w - 1).max(1) as f64;
            img.data[(y + dy) * width + margin + dx] = spec.map.at(t);
        }
    }
    y += glyph + 2 * s;
    let fixed = matches!(spec.range, Range::Fixed { .. });
    let lo_text = format!("{}{}", if fixed { "<=" } else { "" }, number(lo));
    let hi_text = format!("{}{}", if fixed { ">=" } else { "" }, number(hi));
    let range_note = if fixed { "fixed" } else { "p1-p99" };
    text(&mut img, margin, y, &lo_text, s);
    let unit_text = format!("{} ({range_note})", spec.unit);
    let mid = margin + bar_w / 2;
    text(
        &mut img,
        mid.saturating_sub(unit_text.len() * glyph / 2),
        y,
        &unit_text,
        s,
    );
    text(
        &mut img,
        (margin + bar_w).saturating_sub(hi_text.len() * glyph),
        y,
        &hi_text,
        s,
    );
    y += glyph + margin;
    let legend = legend.draw(&mut img, y, s);
    Picture {
        image: img,
        lo,
        hi,
        data_height: h,
        legend,
    }
}

/// The colour map's range: the fixed one, or the 1st-99th percentile of the
/// value pixels (0..1 when there are none).
fn resolve_range(values: &Raster<f32>, classes: &Raster<PixelClass>, range: Range) -> (f64, f64) {
    match range {
        Range::Fixed { lo, hi } => (lo, hi),
        Range::Robust => {
            let mut v: Vec<f32> = values
                .data
                .iter()
                .zip(&classes.data)
                .filter(|(v, c)| **c == PixelClass::Value && v.is_finite())
                .map(|(v, _)| *v)
                .collect();
            if v.is_empty() {
                return (0.0, 1.0);
            }
            let at = |q: f64, v: &mut [f32]| {
                let k = ((v.len() - 1) as f64 * q).round() as usize;
                *v.select_nth_unstable_by(k, f32::total_cmp).1
            };
            let lo = f64::from(at(0.01, &mut v));
            let hi = f64::from(at(0.99, &mut v));
            (lo, hi)
        }
    }
}

/// A number for a label: three significant digits, no exponent.
fn number(v: f64) -> String {
    let a = v.abs();
    if a >= 100.0 || v == 0.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// The legend, laid out once: each marked class with its pixel count and
/// label, left to right, wrapping at the panel's width.
struct Legend {
    /// (class, pixels, label, line, x) per item.
    items: Vec<(PixelClass, usize, String, usize, usize)>,
    /// Lines the items take.
    lines: usize,
    glyph: usize,
    margin: usize,
}

impl Legend {
    fn lay_out(classes: &Raster<PixelClass>, width: usize, glyph: usize, margin: usize) -> Self {
        let counts = counts(classes);
        let mut items = Vec::new();
        let (mut line, mut x) = (0, margin);
        for (class, pixels) in PixelClass::MARKED.into_iter().zip(counts) {
            let share = 100.0 * pixels as f64 / classes.len().max(1) as f64;
            let label = format!("{} {share:.1}%", class.label());
            // Swatch, a space, the label, two spaces.
            let item_w = glyph * (2 + label.len() + 2);
            if x > margin && x + item_w > width {
                line += 1;
                x = margin;
            }
            items.push((class, pixels, label, line, x));
            x += item_w;
        }
        Legend {
            items,
            lines: line + 1,
            glyph,
            margin,
        }
    }

    fn draw(&self, img: &mut Raster<[u8; 3]>, y0: usize, s: usize) -> Vec<LegendEntry> {
        let glyph = self.glyph;
        let mut entries = Vec::new();
        for (class, pixels, label, line, x) in &self.items {
            let (x, y) = (*x, y0 + line * (glyph + self.margin));
            let colour = class.colour().unwrap_or(INK);
            // A swatch with a black frame, so light grey shows on white.
            for dy in 0..glyph {
                for dx in 0..glyph {
                    let edge = dx == 0 || dy == 0 || dx + 1 == glyph || dy + 1 == glyph;
                    img.data[(y + dy) * img.width + x + dx] = if edge { INK } else { colour };
                }
            }
            text(img, x + 2 * glyph, y, label, s);
            entries.push(LegendEntry {
                class: *class,
                pixels: *pixels,
                swatch_xy: (x, y),
            });
        }
        entries
    }
}

/// Pixels of each of [`PixelClass::MARKED`].
fn counts(classes: &Raster<PixelClass>) -> [usize; 4] {
    let mut n = [0; 4];
    for c in &classes.data {
        if let Some(k) = PixelClass::MARKED.iter().position(|m| m == c) {
            n[k] += 1;
        }
    }
    n
}

/// Writes `s` in black at (x, y), each glyph 8x8 scaled by `scale`,
/// clipped at the image's edges; characters outside ASCII draw as '?'.
pub fn text(img: &mut Raster<[u8; 3]>, x: usize, y: usize, s: &str, scale: usize) {
    for (k, ch) in s.chars().enumerate() {
        let code = if ch.is_ascii() {
            ch as usize
        } else {
            '?' as usize
        };
        let rows = font8x8::legacy::BASIC_LEGACY[code];
        let x0 = x + k * 8 * scale;
        for (row, bits) in rows.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (px, py) = (x0 + col * scale + dx, y + row * scale + dy);
                        if px < img.width && py < img.height {
                            img.data[py * img.width + px] = INK;
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_with_holes() -> (Raster<f32>, Raster<PixelClass>) {
        let values = Raster::from_fn(400, 60, |x, _| x as f32);
        let classes = Raster::from_fn(400, 60, |x, y| match (x, y) {
            (0..=9, _) => PixelClass::NoFringe,
            (10..=19, _) => PixelClass::Masked,
            (20..=29, _) => PixelClass::Unreliable,
            (30..=39, 0..=9) => PixelClass::Saturated,
            _ => PixelClass::Value,
        });
        (values, classes)
    }

    #[test]
    fn marked_pixels_and_legend_swatches_carry_their_own_colours() {
        let (values, classes) = ramp_with_holes();
        let spec = PictureSpec {
            title: "test: ramp",
            unit: "px",
            range: Range::Robust,
            map: ColourMap::Viridis,
        };
        let p = draw(&values, &classes, &spec);
        let at = |x: usize, y: usize| p.image.data[y * p.image.width + x];
        for (x, y, class) in [
            (5, 30, PixelClass::NoFringe),
            (15, 30, PixelClass::Masked),
            (25, 30, PixelClass::Unreliable),
            (35, 5, PixelClass::Saturated),
        ] {
            assert_eq!(Some(at(x, y)), class.colour(), "{class:?}");
        }
        // No value pixel takes a marked colour.
        for x in 40..400 {
            let c = at(x, 30);
            assert!(
                PixelClass::MARKED.iter().all(|m| m.colour() != Some(c)),
                "x {x}: {c:?}"
            );
        }
        assert_eq!(p.legend.len(), 4);
        for e in &p.legend {
            let (x, y) = e.swatch_xy;
            assert!(y >= p.data_height, "legend below the data");
            assert_eq!(
                Some(at(x + 3, y + 3)),
                e.class.colour(),
                "{:?} swatch",
                e.class
            );
            assert_eq!(at(x, y), INK, "swatch frame");
        }
        assert_eq!(p.legend[0].pixels, 600);
        assert_eq!(p.legend[3].pixels, 100);
        // Robust range: the 1st..99th percentile of the value pixels (x 30..399,
        // fewer rows at 30..39): 34 and 396.
        assert!(
            (p.lo - 34.0).abs() <= 1.0 && (p.hi - 396.0).abs() <= 1.0,
            "{} {}",
            p.lo,
            p.hi
        );
    }

    #[test]
    fn the_panel_holds_text_and_a_bar_from_the_map_start_to_its_end() {
        let (values, classes) = ramp_with_holes();
        let spec = PictureSpec {
            title: "error vs truth",
            unit: "um",
            range: Range::Fixed { lo: 0.0, hi: 500.0 },
            map: ColourMap::Viridis,
        };
        let p = draw(&values, &classes, &spec);
        assert_eq!((p.lo, p.hi), (0.0, 500.0));
        let w = p.image.width;
        let panel = &p.image.data[p.data_height * w..];
        assert!(
            panel.iter().filter(|c| **c == INK).count() > 200,
            "text drawn"
        );
        // The bar's first and last columns are the map's ends.
        let bar_y = p.data_height + 4 + 8 + 4 + 2;
        assert_eq!(p.image.data[bar_y * w + 4], ColourMap::Viridis.at(0.0));
        let bar_end = 4 + (w - 8).min(320) - 1;
        assert_eq!(
            p.image.data[bar_y * w + bar_end],
            ColourMap::Viridis.at(1.0)
        );
        // A value maps to its place on the fixed range.
        assert_eq!(p.image.data[30 * w + 399], ColourMap::Viridis.at(0.798));
    }

    #[test]
    fn no_value_pixels_still_draw() {
        let values = Raster::filled(64, 48, f32::NAN);
        let classes = Raster::filled(64, 48, PixelClass::NoFringe);
        let p = draw(
            &values,
            &classes,
            &PictureSpec {
                title: "empty",
                unit: "mm",
                range: Range::Robust,
                map: ColourMap::Grey,
            },
        );
        assert_eq!((p.lo, p.hi), (0.0, 1.0));
        assert_eq!(p.legend[0].pixels, 64 * 48);
        assert!(p.image.width >= 64);
    }
}
