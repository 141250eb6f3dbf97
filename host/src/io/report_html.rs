//! `report.html`: one self-contained page per run (pictures embedded as
//! base64 PNG, no network, no external files) with the run's warnings
//! first, its figures, timings and every picture. A short inline script
//! counts pictures that failed to decode and says so on the page.

use base64::Engine;

use super::report::{figure as fig, ScanReport};

/// A picture on the page.
#[derive(Clone, Debug, PartialEq)]
pub struct PagePicture {
    /// File name beside the page (shown under the picture).
    pub file: String,
    /// What it shows.
    pub caption: String,
    /// PNG bytes.
    pub png: Vec<u8>,
}

/// A table of figures: a heading and (name, value) rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Heading.
    pub heading: String,
    /// Rows.
    pub rows: Vec<(String, String)>,
}

/// What a page shows.
#[derive(Clone, Debug, PartialEq)]
pub struct Page {
    /// The page title, e.g. "slscan scan: large-part, sequential".
    pub title: String,
    /// Warnings, shown first.
    pub warnings: Vec<String>,
    /// Figures.
    pub tables: Vec<Table>,
    /// Stage times, milliseconds.
    pub timings_ms: Vec<(String, f64)>,
    /// Pictures.
    pub pictures: Vec<PagePicture>,
    /// What the command printed, shown as it was.
    pub text: Option<String>,
    /// The machine-readable report, shown folded (e.g. report.json's text).
    pub raw: Option<String>,
}

/// Writes a rendered page to `path` (temporary file, then rename).
pub fn write_html(path: &std::path::Path, html: &str) -> Result<(), PageError> {
    super::write_atomically(path, |w| w.write_all(html.as_bytes())).map_err(|source| PageError {
        path: path.to_owned(),
        source,
    })
}

/// The report page could not be written.
#[derive(Debug, thiserror::Error)]
#[error("writing {path}: {source}")]
pub struct PageError {
    /// The page.
    pub path: std::path::PathBuf,
    /// Why.
    pub source: std::io::Error,
}

/// The page as HTML.
pub fn render(page: &Page) -> String {
    let mut h = String::with_capacity(1 << 16);
    h.push_str("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">");
    h.push_str(&format!("<title>{}</title>", escape(&page.title)));
    h.push_str(STYLE);
    h.push_str("</head><body>\n");
    h.push_str(&format!("<h1>{}</h1>\n", escape(&page.title)));
    h.push_str("<p id=\"broken\" class=\"warn\" hidden></p>\n");
    if page.warnings.is_empty() {
        h.push_str("<p id=\"warnings\" class=\"ok\">No warnings.</p>\n");
    } else {
        h.push_str(&format!(
            "<div id=\"warnings\" class=\"warn\"><h2>{} warning{}</h2><ul>",
            page.warnings.len(),
            if page.warnings.len() == 1 { "" } else { "s" }
        ));
        for w in &page.warnings {
            h.push_str(&format!("<li>{}</li>", escape(w)));
        }
        h.push_str("</ul></div>\n");
    }
    for t in &page.tables {
        h.push_str(&format!("<h2>{}</h2><table>", escape(&t.heading)));
        for (k, v) in &t.rows {
            h.push_str(&format!(
                "<tr><th>{}</th><td>{}</td></tr>",
                escape(k),
                escape(v)
            ));
        }
        h.push_str("</table>\n");
    }
    if !page.timings_ms.is_empty() {
        h.push_str("<h2>Timings</h2><table>");
        for (k, ms) in &page.timings_ms {
            h.push_str(&format!(
                "<tr><th>{}</th><td>{ms:.0} ms</td></tr>",
                escape(k)
            ));
        }
        h.push_str("</table>\n");
    }
    if !page.pictures.is_empty() {
        h.push_str("<h2>Pictures</h2><div class=\"pictures\">\n");
        let b64 = base64::engine::general_purpose::STANDARD;
        for p in &page.pictures {
            h.push_str(&format!(
                "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption>{} <code>{}</code></figcaption></figure>\n",
                escape(&p.caption),
                b64.encode(&p.png),
                escape(&p.caption),
                escape(&p.file)
            ));
        }
        h.push_str("</div>\n");
    }
    if let Some(text) = &page.text {
        h.push_str(&format!("<h2>Output</h2><pre>{}</pre>\n", escape(text)));
    }
    if let Some(raw) = &page.raw {
        h.push_str(&format!(
            "<details><summary>Machine-readable report</summary><pre>{}</pre></details>\n",
            escape(raw)
        ));
    }
    h.push_str(SCRIPT);
    h.push_str("</body></html>\n");
    h
}

const STYLE: &str = "<style>body{font-family:sans-serif;max-width:1400px;margin:1em auto;padding:0 1em}\
table{border-collapse:collapse;margin-bottom:1em}th,td{border:1px solid #ccc;padding:2px 8px;text-align:left}\
th{background:#f4f4f4;font-weight:normal}.warn{background:#fff0f0;border:2px solid #c00;padding:0.5em 1em}\
.ok{color:#060}.pictures{display:flex;flex-wrap:wrap;gap:1em}figure{margin:0}img{max-width:660px;display:block}\
</style>";

/// Marks the page (and tells its reader) when a picture did not decode;
/// `data-images` / `data-broken-images` on the body let a test read it.
const SCRIPT: &str = "<script>window.addEventListener('load',function(){\
var imgs=document.images,broken=0;for(var i=0;i<imgs.length;i++){if(!imgs[i].complete||imgs[i].naturalWidth===0)broken++;}\
document.body.setAttribute('data-images',imgs.length);document.body.setAttribute('data-broken-images',broken);\
if(broken>0){var b=document.getElementById('broken');b.hidden=false;b.textContent=broken+' picture(s) failed to load';}});\
</script>";

/// Text safe inside HTML elements and attributes.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// A water scan's restoration, silhouette margin and port figures.
fn underwater_table(u: &super::report::UnderwaterReport) -> Table {
    let per_head = |v: &[usize]| {
        v.iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(" / ")
    };
    let mut restorer = u.restorer.clone();
    if let Some(model) = &u.restorer_model {
        restorer += &format!(
            " ({model}, {} sampler step(s) per tile, {} evaluations)",
            u.sampler_steps.unwrap_or(1),
            u.evaluations
        );
    }
    if let Some(strength) = u.physics_correction {
        restorer += &format!(", physics correction {strength}");
    }
    Table {
        heading: "Under water".into(),
        rows: vec![
            (
                "turbidity".into(),
                u.turbidity.clone().unwrap_or_else(|| "not named".into()),
            ),
            ("restorer".into(), restorer),
            (
                "forward-scatter PSF".into(),
                format!("sigma {:.2} px", u.psf_sigma_px),
            ),
            (
                "restoration".into(),
                format!(
                    "{} sets, {} frames in {:.0} ms; {} frame pixels masked",
                    u.sets_restored, u.frames_restored, u.restore_time_ms, u.masked_pixels
                ),
            ),
            (
                "silhouette margin".into(),
                format!(
                    "{} PSF sigmas: {} decoded pixels left out per head",
                    u.edge_margin_sigmas,
                    per_head(&u.blur_edge_pixels)
                ),
            ),
            (
                "triangulation".into(),
                format!(
                    "{}; {} pixels missed the port per head",
                    u.triangulation,
                    per_head(&u.port_misses)
                ),
            ),
        ],
    }
}

/// The page of a scan.
pub fn scan_page(report: &ScanReport, pictures: &[PagePicture]) -> String {
    let mut tables = vec![Table {
        heading: "Scan".into(),
        rows: vec![
            ("scene".into(), report.scene.clone()),
            ("mode".into(), report.mode.clone()),
            (
                "camera".into(),
                format!("{} x {} px", report.camera_px.0, report.camera_px.1),
            ),
            (
                "projector".into(),
                format!("{} x {} px", report.projector_px.0, report.projector_px.1),
            ),
            (
                "fringe periods".into(),
                report
                    .periods_px
                    .iter()
                    .map(|p| format!("{p:.2}"))
                    .collect::<Vec<_>>()
                    .join(", ")
                    + " px",
            ),
            ("phase steps".into(), report.steps.to_string()),
            ("calibration".into(), report.calibration.clone()),
            (
                "ground truth".into(),
                if report.surface_samples.is_some() {
                    "digital twin".into()
                } else {
                    "none (hardware): accuracy figures are n/a".into()
                },
            ),
        ],
    }];
    for h in &report.heads {
        let mut rows = vec![
            ("points".into(), h.points.to_string()),
            ("RMSE vs truth".into(), fig(h.rmse_um, 1, "um")),
            (
                "predicted RMS".into(),
                fig(Some(h.predicted_rms_um), 1, "um"),
            ),
            ("median error".into(), fig(h.median_error_um, 1, "um")),
            (
                "points over 1 mm off".into(),
                h.outliers_over_1mm.map_or("n/a".into(), |n| n.to_string()),
            ),
            ("coverage".into(), fig(h.coverage, 3, "")),
            (
                "overlap RMSE vs truth".into(),
                fig(h.overlap_rmse_um, 1, "um"),
            ),
        ];
        let e = &h.exposure;
        let pct = |f: f64| format!("{:.2} %", 100.0 * f);
        rows.push((
            format!("exposure ({})", e.kind),
            format!(
                "{} images; fringes at {} x the standard exposure, {} frame(s) averaged per pattern; saturated {}, below the modulation floor {}",
                e.images,
                e.exposure_scales
                    .iter()
                    .map(|s| format!("{s:.3}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                e.frames_per_pattern,
                pct(e.saturated_fraction),
                pct(e.below_modulation_floor_fraction)
            ),
        ));
        if let Some(a) = &e.adaptive {
            rows.push((
                "adaptive projection".into(),
                format!(
                    "before: saturated {}, below the floor {}; exposure limited by {}; {} pixels lowered ({} by their phase, {} by homography over {} clusters, {} unplaced); {} saturate at the lowest flood, {} cannot be held; {} left out over a level step",
                    pct(a.saturated_fraction_before),
                    pct(a.below_modulation_floor_fraction_before),
                    a.exposure_limited_by,
                    a.lowered_pixels,
                    a.mapped_by_phase_pixels,
                    a.mapped_by_homography_pixels,
                    a.clusters,
                    a.unmapped_pixels,
                    a.saturates_at_lowest_pixels,
                    a.cannot_hold_pixels,
                    a.level_step_pixels
                ),
            ));
        }
        if let Some(d) = &h.dealias {
            rows.push((
                format!("de-aliasing ({})", d.method),
                format!(
                    "{} of {} overlap pixels separated ({} ill-posed, {} misfit, {} unsolved, {} inconsistent, {} bad input), {} ms; first frame's error against the own projector alone {}",
                    d.separated_pixels,
                    d.attempted_pixels,
                    d.ill_posed_pixels,
                    d.misfit_pixels,
                    d.unsolved_pixels,
                    d.inconsistent_pixels,
                    d.bad_input_pixels,
                    d.time_ms,
                    fig(d.error_vs_clean_rms_8bit, 2, "(8-bit RMS)")
                ),
            ));
        }
        if let Some(g) = &h.registration {
            rows.push((
                "multi-view registration".into(),
                format!(
                    "moved the calibrated pose {:.4} deg / {:.1} um, fitness {:.3}; pose vs truth {} / {}",
                    g.rotation_deg,
                    g.translation_um,
                    g.fitness,
                    fig(h.pose_error_vs_truth_deg, 4, "deg"),
                    fig(h.pose_error_vs_truth_um, 1, "um")
                ),
            ));
        }
        for s in &h.spheres {
            rows.push((
                format!("sphere {}", s.name),
                format!(
                    "radius {:.4} mm (error {:+.1} um), centre error {:.1} um, fit RMSE {:.1} um (noise limit {:.1} um)",
                    s.radius_mm, s.radius_error_um, s.centre_error_um, s.fit_rmse_um, s.noise_limit_um
                ),
            ));
        }
        tables.push(Table {
            heading: format!("Head {}", h.name),
            rows,
        });
    }
    let f = &report.fused;
    let mut rows = vec![
        ("points".into(), f.points.to_string()),
        (
            "RMSE vs truth (point to plane)".into(),
            fig(f.rmse_um, 1, "um"),
        ),
        ("coverage".into(), fig(f.coverage, 3, "")),
    ];
    match &f.icp {
        Some(icp) => rows.push((
            "ICP correction of the calibrated pose".into(),
            format!(
                "{:.4} deg / {:.1} um, overlap RMSE {:.1} um, fitness {:.3}, {} iterations{}",
                icp.rotation_deg,
                icp.translation_um,
                icp.overlap_rmse_um,
                icp.fitness,
                icp.iterations,
                if icp.converged {
                    ""
                } else {
                    " (not converged)"
                }
            ),
        )),
        None if f.registration.is_none() => rows.push(("ICP".into(), "none".into())),
        None => {}
    }
    if let Some(r) = &f.registration {
        rows.push((
            "multi-view registration".into(),
            format!(
                "{} in {} iterations; calibration self-check (no truth needed): {}",
                if r.converged {
                    "converged"
                } else {
                    "not converged"
                },
                r.iterations,
                r.verdict
            ),
        ));
        for p in &r.pairs {
            rows.push((
                format!("overlap {}", p.heads),
                format!(
                    "RMSE {:.1} um over {} point pairs (noise predicts {}), shape disagreement {}",
                    p.overlap_rmse_um,
                    p.inliers,
                    fig(p.predicted_overlap_um, 1, "um"),
                    fig(p.shape_disagreement_um, 1, "um")
                ),
            ));
        }
    }
    if let (Some(deg), Some(um)) = (f.pose_error_vs_truth_deg, f.pose_error_vs_truth_um) {
        rows.push((
            "head-to-head pose used vs truth".into(),
            format!("{deg:.4} deg / {um:.1} um"),
        ));
    }
    if let Some(c) = &f.self_check {
        rows.push((
            "calibration self-check (no truth needed)".into(),
            format!(
                "{}: pose corrected by {:.3} deg / {:.2} mm; shape disagreement {} (noise alone {}); overlap residual {:.0} um (noise predicts {:.0} um)",
                c.verdict,
                c.pose_correction_deg,
                c.pose_correction_mm,
                fig(c.shape_disagreement_um, 0, "um"),
                fig(c.shape_noise_um, 0, "um"),
                c.overlap_rmse_um,
                c.predicted_overlap_um
            ),
        ));
    }
    if let Some(why) = &f.failure {
        rows.push(("fusion failed".into(), why.clone()));
    }
    tables.push(Table {
        heading: "Fused cloud".into(),
        rows,
    });
    if let Some(u) = &report.underwater {
        tables.push(underwater_table(u));
    }
    render(&Page {
        title: format!("slscan scan: {}, {}", report.scene, report.mode),
        warnings: report.warnings.clone(),
        tables,
        timings_ms: report
            .timings_ms
            .iter()
            .map(|(k, v)| (k.clone(), *v))
            .collect(),
        pictures: pictures.to_vec(),
        text: None,
        raw: serde_json::to_string_pretty(report).ok(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_escapes_text_embeds_pictures_and_lists_warnings() {
        let page = Page {
            title: "scan <a & b>".into(),
            warnings: vec!["pose off by 1.5 deg".into()],
            tables: vec![Table {
                heading: "Head A".into(),
                rows: vec![("RMSE".into(), "93.9 um".into())],
            }],
            timings_ms: vec![("capture".into(), 812.0)],
            pictures: vec![PagePicture {
                file: "depth_a.png".into(),
                caption: "depth".into(),
                png: vec![0x89, b'P', b'N', b'G'],
            }],
            text: Some("fx 4000.1 <px>".into()),
            raw: Some("{\"x\": 1}".into()),
        };
        let html = render(&page);
        assert!(html.contains("<title>scan &lt;a &amp; b&gt;</title>"));
        assert!(html.contains("<li>pose off by 1.5 deg</li>"));
        assert!(html.contains("src=\"data:image/png;base64,iVBORw==\""));
        assert!(html.contains("812 ms"));
        assert!(html.contains("{&quot;x&quot;: 1}"));
        assert!(html.contains("<pre>fx 4000.1 &lt;px&gt;</pre>"));
        assert!(!html.contains("http"), "no network references");
        let quiet = render(&Page {
            warnings: vec![],
            ..page
        });
        assert!(quiet.contains("No warnings."));
    }
}
