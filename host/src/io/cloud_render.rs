//! Pictures of a point cloud: a z-buffered point splat renderer through a
//! pinhole camera, Lambert-shaded from the points' normals (or shaded by
//! depth when there are none). Pure: points in, an RGB raster out.
//!
//! Ours because the job is small (a few dozen lines) and a 3D engine crate
//! would pull a GPU stack into a CLI that only writes PNGs.

use nalgebra::{Isometry3, Point3, Vector3};

use crate::raster::Raster;

/// Background colour of the pictures.
pub const BACKGROUND: [u8; 3] = [24, 24, 28];

/// Surface colour at full light.
const SURFACE: [f32; 3] = [235.0, 225.0, 205.0];

/// Share of the light that reaches surfaces whatever their normal.
const AMBIENT: f32 = 0.15;

/// A virtual camera: computer-vision convention, x right, y down, z forward.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CloudView {
    /// Camera frame from the cloud's frame.
    pub camera_from_cloud: Isometry3<f64>,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Picture width, pixels.
    pub width: u32,
    /// Picture height, pixels.
    pub height: u32,
}

impl CloudView {
    /// A camera at `eye` looking at `target`, with `down` (in the cloud's
    /// frame) pointing down the picture.
    pub fn looking_at(
        eye: &Point3<f64>,
        target: &Point3<f64>,
        down: &Vector3<f64>,
        fov_deg: f64,
        size_px: (u32, u32),
    ) -> Self {
        // face_towards puts local +z on the line of sight and local +y
        // along `down`: exactly the x-right / y-down / z-forward camera.
        let cloud_from_camera = Isometry3::face_towards(eye, target, down);
        CloudView {
            camera_from_cloud: cloud_from_camera.inverse(),
            fov_deg,
            width: size_px.0,
            height: size_px.1,
        }
    }

    /// A view that frames the finite `points` (1st to 99th percentile box),
    /// looking along the cloud frame's +z (y down) turned by `yaw_deg`
    /// about the frame's y axis and `pitch_deg` about the turned x axis.
    /// `None` when no point is finite.
    pub fn framing(
        points: &[[f32; 3]],
        yaw_deg: f64,
        pitch_deg: f64,
        size_px: (u32, u32),
    ) -> Option<Self> {
        let (lo, hi) = robust_box(points)?;
        let centre = Point3::from((lo + hi) / 2.0);
        let radius = ((hi - lo) / 2.0).norm().max(1e-6);
        let fov_deg: f64 = 40.0;
        // Far enough that a sphere of `radius` fits the narrower field.
        let aspect = f64::from(size_px.1) / f64::from(size_px.0.max(1));
        let half_fov = (fov_deg.to_radians() / 2.0).tan() * aspect.min(1.0);
        let distance = 1.1 * radius / half_fov.atan().sin();
        let rotation =
            nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), yaw_deg.to_radians())
                * nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), pitch_deg.to_radians());
        let sight = rotation * Vector3::z();
        let down = rotation * Vector3::y();
        let eye = centre - distance * sight;
        Some(CloudView::looking_at(
            &eye, &centre, &down, fov_deg, size_px,
        ))
    }

    /// Focal length, pixels.
    fn focal_px(&self) -> f64 {
        f64::from(self.width) / 2.0 / (self.fov_deg.to_radians() / 2.0).tan()
    }
}

/// The 1st..99th percentile box of the finite points (`None` if none).
fn robust_box(points: &[[f32; 3]]) -> Option<(Vector3<f64>, Vector3<f64>)> {
    let finite: Vec<&[f32; 3]> = points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .collect();
    if finite.is_empty() {
        return None;
    }
    let mut lo = Vector3::zeros();
    let mut hi = Vector3::zeros();
    for axis in 0..3 {
        let mut v: Vec<f32> = finite.iter().map(|p| p[axis]).collect();
        v.sort_by(f32::total_cmp);
        let at = |q: f64| f64::from(v[((v.len() - 1) as f64 * q).round() as usize]);
        lo[axis] = at(0.01);
        hi[axis] = at(0.99);
    }
    Some((lo, hi))
}

/// Renders `points` (with optional unit `normals`, one per point) as seen
/// by `view`: each point a square splat of `splat_radius_px`, the nearest
/// one winning each pixel. With normals, Lambert shading under a light at
/// the camera (sign-blind, so unoriented normals shade the same); without,
/// nearer is brighter. Non-finite points are skipped.
pub fn render_cloud(
    points: &[[f32; 3]],
    normals: Option<&[[f32; 3]]>,
    view: &CloudView,
    splat_radius_px: u32,
) -> Raster<[u8; 3]> {
    let (w, h) = (view.width as usize, view.height as usize);
    let mut depth = vec![f64::INFINITY; w * h];
    let mut shade = vec![f32::NAN; w * h];
    let f = view.focal_px();
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let r = splat_radius_px as i64;
    // Headlight a little above and left of the lens: relief reads better
    // than under light straight along the line of sight.
    let light = Vector3::new(-0.3, -0.4, -1.0).normalize();
    for (i, p) in points.iter().enumerate() {
        let q =
            view.camera_from_cloud * Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
        if !(q.z > 1e-9 && q.x.is_finite() && q.y.is_finite()) {
            continue;
        }
        let value = match normals {
            Some(ns) => {
                let n = ns.get(i).copied().unwrap_or([f32::NAN; 3]);
                let n = view.camera_from_cloud.rotation
                    * Vector3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2]));
                let lambert = n.dot(&light).abs();
                if lambert.is_finite() {
                    AMBIENT + (1.0 - AMBIENT) * lambert as f32
                } else {
                    AMBIENT
                }
            }
            None => f32::NAN, // filled from depth below
        };
        let u = (f * q.x / q.z + cx).floor() as i64;
        let v = (f * q.y / q.z + cy).floor() as i64;
        for y in (v - r).max(0)..(v + r + 1).min(h as i64) {
            for x in (u - r).max(0)..(u + r + 1).min(w as i64) {
                let k = y as usize * w + x as usize;
                if q.z < depth[k] {
                    depth[k] = q.z;
                    shade[k] = value;
                }
            }
        }
    }
    if normals.is_none() {
        shade_by_depth(&depth, &mut shade);
    }
    Raster {
        width: w,
        height: h,
        data: depth
            .iter()
            .zip(&shade)
            .map(|(d, s)| {
                if d.is_finite() {
                    SURFACE.map(|c| (c * s.clamp(0.0, 1.0)).round() as u8)
                } else {
                    BACKGROUND
                }
            })
            .collect(),
    }
}

/// Nearest drawn pixel full bright, farthest at the ambient level.
fn shade_by_depth(depth: &[f64], shade: &mut [f32]) {
    let drawn = depth.iter().filter(|d| d.is_finite());
    let near = drawn.clone().fold(f64::INFINITY, |a, &b| a.min(b));
    let far = drawn.fold(f64::NEG_INFINITY, |a, &b| a.max(b));
    let span = (far - near).max(1e-12);
    for (s, d) in shade.iter_mut().zip(depth) {
        if d.is_finite() {
            *s = 1.0 - (1.0 - AMBIENT) * ((d - near) / span) as f32;
        }
    }
}

/// A splat radius that closes the gaps between `points` projected points
/// on a `size_px` picture that they roughly fill: half the mean spacing,
/// 1 to 4 pixels.
pub fn splat_radius_for(points: usize, size_px: (u32, u32)) -> u32 {
    let px_per_point = f64::from(size_px.0) * f64::from(size_px.1) / points.max(1) as f64;
    (0.5 * px_per_point.sqrt()).ceil().clamp(1.0, 4.0) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view_along_z() -> CloudView {
        CloudView::looking_at(
            &Point3::origin(),
            &Point3::new(0.0, 0.0, 1.0),
            &Vector3::y(),
            60.0,
            (64, 48),
        )
    }

    #[test]
    fn looking_along_z_with_y_down_is_the_identity_camera() {
        let v = view_along_z();
        assert!((v.camera_from_cloud.rotation.angle()) < 1e-12);
        assert!(v.camera_from_cloud.translation.vector.norm() < 1e-12);
    }

    #[test]
    fn a_point_right_and_below_lands_right_and_below_the_centre() {
        let v = view_along_z();
        let img = render_cloud(&[[0.2, 0.1, 1.0]], None, &v, 0);
        let lit: Vec<usize> = (0..img.data.len())
            .filter(|&k| img.data[k] != BACKGROUND)
            .collect();
        assert_eq!(lit.len(), 1);
        let (x, y) = (lit[0] % 64, lit[0] / 64);
        assert!(x > 32 && y > 24, "({x}, {y})");
    }

    #[test]
    fn nearer_points_hide_farther_ones_and_facing_normals_shade_brighter() {
        let v = view_along_z();
        let far = [0.0, 0.0, 2.0];
        let near = [0.0, 0.0, 1.0];
        let facing = [0.0f32, 0.0, -1.0];
        let grazing = [1.0f32, 0.0, 0.0];
        // Near grazing point in front of a far facing one: the near one wins.
        let img = render_cloud(&[far, near], Some(&[facing, grazing]), &v, 1);
        let centre = img.data[24 * 64 + 32];
        let img_far = render_cloud(&[far], Some(&[facing]), &v, 1);
        let centre_far = img_far.data[24 * 64 + 32];
        assert!(centre[0] < centre_far[0], "{centre:?} vs {centre_far:?}");
        // The same with the order swapped: the z-buffer, not the order, decides.
        let swapped = render_cloud(&[near, far], Some(&[grazing, facing]), &v, 1);
        assert_eq!(swapped.data, img.data);
        // Flipped normals shade the same.
        let flipped = render_cloud(&[far], Some(&[[0.0, 0.0, 1.0]]), &v, 1);
        assert_eq!(flipped.data, img_far.data);
    }

    #[test]
    fn nothing_finite_renders_background_and_framing_declines() {
        let nan = [[f32::NAN, 0.0, 1.0]];
        let img = render_cloud(&nan, None, &view_along_z(), 2);
        assert!(img.data.iter().all(|&c| c == BACKGROUND));
        assert!(CloudView::framing(&nan, 0.0, 0.0, (64, 48)).is_none());
        assert!(render_cloud(&[], None, &view_along_z(), 2)
            .data
            .iter()
            .all(|&c| c == BACKGROUND));
    }

    #[test]
    fn framing_puts_a_plane_patch_in_view_from_two_sides() {
        let mut pts = Vec::new();
        for i in 0..40 {
            for j in 0..30 {
                pts.push([i as f32 * 0.01 + 1.0, j as f32 * 0.01, 3.0]);
            }
        }
        for (yaw, pitch) in [(0.0, 0.0), (40.0, 25.0)] {
            let v = CloudView::framing(&pts, yaw, pitch, (64, 48)).unwrap();
            let img = render_cloud(&pts, None, &v, splat_radius_for(pts.len(), (64, 48)));
            let lit = img.data.iter().filter(|&&c| c != BACKGROUND).count();
            // Seen, and not spilling over the whole picture.
            assert!(lit > 200 && lit < 64 * 48, "yaw {yaw}: {lit} px");
            // The edges stay background: the patch is framed, not cropped.
            assert_eq!(img.data[0], BACKGROUND);
            assert_eq!(img.data[64 * 48 - 1], BACKGROUND);
        }
    }
}
