//! Per-camera geometry of one scene pose, computed once and reused by every
//! pattern of a sequence: the camera ray of each pixel, its surface point,
//! the projector coordinates of that point, the shadow test toward each
//! projector, and the radiometric gain from projector pixel to camera pixel.

use nalgebra::Point3;
use rayon::prelude::*;

use super::device::Rig;
use super::error::TwinError;
use super::geometry::{Ray, V3};
use super::medium::Medium;
use super::scene::PosedScene;

/// Why a camera pixel is or is not lit by one projector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Illum {
    /// The projector lights this surface point.
    Lit = 0,
    /// The point faces the projector and is on its DMD, but something blocks the light.
    Shadowed = 1,
    /// The point projects outside the DMD (or behind the projector).
    OutsideDmd = 2,
    /// The surface faces away from the projector.
    BackFacing = 3,
    /// The camera ray hits nothing.
    NoSurface = 4,
}

/// What one projector contributes to each camera pixel.
#[derive(Clone, Debug)]
pub struct ProjectorView {
    /// DMD coordinate of each pixel's surface point (NaN when none).
    pub uv_px: Vec<[f32; 2]>,
    /// Irradiance-to-signal gain per LED band (0 unless lit): LED power x
    /// inverse-square falloff x (albedo cos + specular) x water transmittance.
    pub gain: Vec<[f32; 3]>,
    /// Lighting state.
    pub illum: Vec<Illum>,
}

/// The cached geometry of one camera for one scene pose.
#[derive(Clone, Debug)]
pub struct CameraGeometry {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// z of the surface point in the camera frame, metres (NaN: no surface).
    pub depth_m: Vec<f32>,
    /// World surface point, metres (NaN: no surface).
    pub point_m: Vec<[f32; 3]>,
    /// World unit normal facing the camera (NaN: no surface).
    pub normal: Vec<[f32; 3]>,
    /// Object index (u16::MAX: no surface).
    pub object: Vec<u16>,
    /// Ambient signal per second per band: albedo x surface ambient + direct ambient.
    pub ambient: Vec<[f32; 3]>,
    /// Length of the camera-side water path, metres (0 in air).
    pub water_path_m: Vec<f32>,
    /// One view per projector of the rig.
    pub projectors: Vec<ProjectorView>,
}

/// Per-pixel result of the ray casting, before it is split into columns.
struct PixelGeom {
    depth: f32,
    point: [f32; 3],
    normal: [f32; 3],
    object: u16,
    ambient: [f32; 3],
    water: f32,
    proj: Vec<([f32; 2], [f32; 3], Illum)>,
}

const NAN2: [f32; 2] = [f32::NAN; 2];
const NAN3: [f32; 3] = [f32::NAN; 3];

fn f3(v: &V3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

impl CameraGeometry {
    /// Casts every pixel's ray into the posed scene and tests each projector.
    pub fn new(scene: &PosedScene, rig: &Rig, camera: usize) -> Result<CameraGeometry, TwinError> {
        rig.validate()?;
        let cam = rig.cameras.get(camera).ok_or(TwinError::NoSuchCamera {
            index: camera,
            count: rig.cameras.len(),
        })?;
        let (w, h) = (cam.model.intrinsics.width, cam.model.intrinsics.height);
        let pixels: Vec<PixelGeom> = (0..h)
            .into_par_iter()
            .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| pixel(scene, rig, camera, x as f64, y as f64))
            .collect();
        let np = rig.projectors.len();
        let mut g = CameraGeometry {
            width: w,
            height: h,
            depth_m: Vec::with_capacity(pixels.len()),
            point_m: Vec::with_capacity(pixels.len()),
            normal: Vec::with_capacity(pixels.len()),
            object: Vec::with_capacity(pixels.len()),
            ambient: Vec::with_capacity(pixels.len()),
            water_path_m: Vec::with_capacity(pixels.len()),
            projectors: (0..np)
                .map(|_| ProjectorView {
                    uv_px: Vec::with_capacity(pixels.len()),
                    gain: Vec::with_capacity(pixels.len()),
                    illum: Vec::with_capacity(pixels.len()),
                })
                .collect(),
        };
        for p in pixels {
            g.depth_m.push(p.depth);
            g.point_m.push(p.point);
            g.normal.push(p.normal);
            g.object.push(p.object);
            g.ambient.push(p.ambient);
            g.water_path_m.push(p.water);
            for (view, (uv, gain, il)) in g.projectors.iter_mut().zip(p.proj) {
                view.uv_px.push(uv);
                view.gain.push(gain);
                view.illum.push(il);
            }
        }
        Ok(g)
    }
}

/// The camera ray of pixel (x, y) in the world, and where its water path starts.
fn camera_ray(rig: &Rig, camera: usize, x: f64, y: f64) -> Option<Ray> {
    let model = &rig.cameras[camera].model;
    match &rig.medium {
        Medium::Air => Some(model.pixel_ray(x, y)),
        Medium::Water(water) => {
            let local = water.refract_out(&model.local_dir(x, y))?;
            let pose = &model.world_from_device;
            Some(Ray {
                origin: pose.transform_point(&Point3::from(local.origin)).coords,
                dir: pose.rotation * local.dir,
            })
        }
    }
}

fn pixel(scene: &PosedScene, rig: &Rig, camera: usize, x: f64, y: f64) -> PixelGeom {
    let np = rig.projectors.len();
    let s = scene.scene();
    let direct = s.ambient_direct.map(|a| a as f32);
    let miss = PixelGeom {
        depth: f32::NAN,
        point: NAN3,
        normal: NAN3,
        object: u16::MAX,
        ambient: direct,
        water: 0.0,
        proj: vec![(NAN2, [0.0; 3], Illum::NoSurface); np],
    };
    let Some(ray) = camera_ray(rig, camera, x, y) else {
        return miss;
    };
    let Some(hit) = scene.intersect(&ray, 0.0, f64::INFINITY) else {
        return miss;
    };
    let cam_model = &rig.cameras[camera].model;
    let p_cam = cam_model
        .world_from_device
        .inverse_transform_point(&Point3::from(hit.point_m));
    let material = &s.objects[hit.object].material;
    let albedo = material.albedo.at(&hit.local_m);
    let (water_c, view_to) = match rig.medium {
        Medium::Air => (0.0, cam_model.centre()),
        Medium::Water(_) => (hit.t_m, ray.origin),
    };
    let v = (view_to - hit.point_m).normalize();
    let ambient = [0, 1, 2].map(|b| albedo[b] * s.ambient_surface[b] as f32 + direct[b]);
    let proj = rig
        .projectors
        .iter()
        .map(|pr| {
            let model = &pr.model;
            let q = model
                .world_from_device
                .inverse_transform_point(&Point3::from(hit.point_m))
                .coords;
            // Where the light leaves the device: its centre, or its port crossing in water.
            let (aim_local, water_p) = match &rig.medium {
                Medium::Air => (Some(V3::zeros()), 0.0),
                Medium::Water(wtr) => match wtr.port_crossing(&q) {
                    Some(c) => (Some(c), (q - c).norm()),
                    None => (None, 0.0),
                },
            };
            let Some(aim_local) = aim_local else {
                return (NAN2, [0.0; 3], Illum::OutsideDmd);
            };
            let dir_local = if aim_local.norm() > 0.0 { aim_local } else { q };
            let Some(uv) = model.project_local(&dir_local) else {
                return (NAN2, [0.0; 3], Illum::OutsideDmd);
            };
            let uv32 = [uv[0] as f32, uv[1] as f32];
            if !model.contains(uv) {
                return (uv32, [0.0; 3], Illum::OutsideDmd);
            }
            let aim = model
                .world_from_device
                .transform_point(&Point3::from(aim_local))
                .coords;
            let l = (aim - hit.point_m).normalize();
            let cos_i = hit.normal.dot(&l);
            if cos_i <= 0.0 || hit.normal.dot(&v) <= 0.0 {
                return (uv32, [0.0; 3], Illum::BackFacing);
            }
            // Start the shadow ray just off the surface to avoid self-hits.
            let start = hit.point_m + hit.normal * 1e-6;
            if scene.occluded(&start, &aim) {
                return (uv32, [0.0; 3], Illum::Shadowed);
            }
            let falloff = (pr.reference_distance_m / q.norm()).powi(2);
            let half = (l + v).normalize();
            let spec = if material.specular > 0.0 {
                material.specular as f64
                    * hit
                        .normal
                        .dot(&half)
                        .max(0.0)
                        .powf(material.shininess as f64)
            } else {
                0.0
            };
            let trans = match &rig.medium {
                Medium::Air => [1.0; 3],
                Medium::Water(wtr) => wtr.transmittance(water_p + water_c),
            };
            let gain = [0, 1, 2].map(|b| {
                (pr.led_power[b] * falloff * (albedo[b] as f64 * cos_i + spec) * trans[b]) as f32
            });
            (uv32, gain, Illum::Lit)
        })
        .collect();
    PixelGeom {
        depth: p_cam.z as f32,
        point: f3(&hit.point_m),
        normal: f3(&hit.normal),
        object: hit.object as u16,
        ambient,
        water: water_c as f32,
        proj,
    }
}
