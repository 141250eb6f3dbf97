//! Per-camera geometry of one scene pose, computed once and reused by every
//! pattern of a sequence: the camera ray of each pixel, its surface point,
//! the projector coordinates of that point, the shadow test toward each
//! projector, and the radiometric gain from projector pixel to camera pixel.

use nalgebra::Point3;
use rayon::prelude::*;

use super::device::{Pinhole, Projector, Rig};
use super::error::TwinError;
use super::geometry::{Frame, Ray, V3};
use super::huge_pages::advised;
use super::medium::Medium;
use super::mesh::PACKET;
use super::scene::{Hit, Material, PosedScene};

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
    /// Ambient signal per second per band: albedo x (scene + material ambient) + direct ambient.
    pub ambient: Vec<[f32; 3]>,
    /// Length of the camera-side water path, metres (0 in air).
    pub water_path_m: Vec<f32>,
    /// One view per projector of the rig.
    pub projectors: Vec<ProjectorView>,
    /// Lit by two or more projectors (the aliased overlap of seed 000).
    pub overlap: Vec<bool>,
}

/// One image row of every output of [`CameraGeometry`]: rows are filled in
/// parallel straight into the final maps, so no row is copied after.
struct RowOut<'a> {
    depth: &'a mut [f32],
    point: &'a mut [[f32; 3]],
    normal: &'a mut [[f32; 3]],
    object: &'a mut [u16],
    ambient: &'a mut [[f32; 3]],
    water: &'a mut [f32],
    proj: Vec<ProjRow<'a>>,
}

/// One image row of one [`ProjectorView`].
struct ProjRow<'a> {
    uv_px: &'a mut [[f32; 2]],
    gain: &'a mut [[f32; 3]],
    illum: &'a mut [Illum],
}

impl ProjRow<'_> {
    fn set(&mut self, x: usize, (uv, gain, illum): ([f32; 2], [f32; 3], Illum)) {
        self.uv_px[x] = uv;
        self.gain[x] = gain;
        self.illum[x] = illum;
    }
}

impl ProjectorView {
    /// `n` pixels of nothing (zeroed maps cost no write until filled).
    fn empty(n: usize) -> ProjectorView {
        ProjectorView {
            uv_px: advised(vec![[0.0; 2]; n]),
            gain: advised(vec![[0.0; 3]; n]),
            illum: vec![Illum::NoSurface; n],
        }
    }
}

impl CameraGeometry {
    /// A `width` x `height` geometry of `projectors` views, all zero until
    /// filled: zeroed maps are fresh pages the parallel fill touches first.
    fn empty(width: u32, height: u32, projectors: usize) -> CameraGeometry {
        let n = (width * height) as usize;
        CameraGeometry {
            width,
            height,
            depth_m: advised(vec![0.0; n]),
            point_m: advised(vec![[0.0; 3]; n]),
            normal: advised(vec![[0.0; 3]; n]),
            object: vec![0; n],
            ambient: advised(vec![[0.0; 3]; n]),
            water_path_m: advised(vec![0.0; n]),
            projectors: (0..projectors).map(|_| ProjectorView::empty(n)).collect(),
            overlap: Vec::new(),
        }
    }

    /// Every output split into rows, for a parallel fill.
    fn rows_mut(&mut self) -> Vec<RowOut<'_>> {
        let w = self.width as usize;
        let mut proj: Vec<_> = self
            .projectors
            .iter_mut()
            .map(|p| {
                p.uv_px
                    .chunks_mut(w)
                    .zip(p.gain.chunks_mut(w))
                    .zip(p.illum.chunks_mut(w))
            })
            .collect();
        self.depth_m
            .chunks_mut(w)
            .zip(self.point_m.chunks_mut(w))
            .zip(self.normal.chunks_mut(w))
            .zip(self.object.chunks_mut(w))
            .zip(self.ambient.chunks_mut(w))
            .zip(self.water_path_m.chunks_mut(w))
            .map(
                |(((((depth, point), normal), object), ambient), water)| RowOut {
                    depth,
                    point,
                    normal,
                    object,
                    ambient,
                    water,
                    proj: proj
                        .iter_mut()
                        .filter_map(Iterator::next)
                        .map(|((uv_px, gain), illum)| ProjRow { uv_px, gain, illum })
                        .collect(),
                },
            )
            .collect()
    }
}

/// Most rays per pixel and axis [`CameraGeometry::sampled`] accepts (256 per pixel).
pub const MAX_PIXEL_SAMPLES: u32 = 16;

const NAN2: [f32; 2] = [f32::NAN; 2];
const NAN3: [f32; 3] = [f32::NAN; 3];

fn f3(v: &V3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

impl CameraGeometry {
    /// Casts every pixel's ray (through its centre) into the posed scene and tests
    /// each projector.
    pub fn new(scene: &PosedScene, rig: &Rig, camera: usize) -> Result<CameraGeometry, TwinError> {
        Self::sampled(scene, rig, camera, 1)
    }

    /// Casts `samples` x `samples` rays per camera pixel, on a regular grid over the
    /// pixel's area, into a geometry `samples` times as wide and high: sample (X, Y)
    /// looks through camera pixel `((X + 0.5) / samples - 0.5, (Y + 0.5) / samples -
    /// 0.5)` (pixel centres at integers). Averaging the light of a pixel's samples is
    /// what a real pixel does: it integrates over its area, so a sharp edge gives a
    /// grey pixel whose level says where the edge crosses it. `samples` = 1 is
    /// [`Self::new`].
    pub fn sampled(
        scene: &PosedScene,
        rig: &Rig,
        camera: usize,
        samples: u32,
    ) -> Result<CameraGeometry, TwinError> {
        Self::from_rays(scene, rig, &CameraRays::new(rig, camera, samples)?)
    }

    /// Casts `rays` (computed for `rig`) into the posed scene: what
    /// [`Self::sampled`] does after computing the rays, so the poses of a
    /// moving scene seen by a fixed rig share them.
    pub fn from_rays(
        scene: &PosedScene,
        rig: &Rig,
        rays: &CameraRays,
    ) -> Result<CameraGeometry, TwinError> {
        rig.validate()?;
        rays.check_rig(rig)?;
        scene.scene().validate()?;
        let (w, h) = (rays.width, rays.height);
        let camera = rays.camera;
        let mut g = CameraGeometry::empty(w, h, rig.projectors.len());
        let frames = DeviceFrames::new(rig, camera);
        g.rows_mut()
            .into_par_iter()
            .zip(rays.rays.par_chunks(w as usize))
            .for_each(|(mut row, row_rays)| {
                for (c, chunk) in row_rays.chunks(PACKET).enumerate() {
                    pixels(scene, rig, &frames, chunk, &mut row, c * PACKET);
                }
            });
        let views = &g.projectors;
        g.overlap = (0..(w * h) as usize)
            .into_par_iter()
            .map(|i| views.iter().filter(|p| p.illum[i] == Illum::Lit).count() >= 2)
            .collect();
        Ok(g)
    }
}

/// The world ray of every (sub)pixel of one camera, out of its port into
/// the water when there is one: they depend on the rig alone (lens
/// distortion is undone by Newton steps per pixel), so a fixed rig computes
/// them once for all the poses of a moving scene.
#[derive(Clone, Debug)]
pub struct CameraRays {
    camera: usize,
    /// The camera and medium the rays were computed for, to refuse another rig.
    model: Pinhole,
    medium: Medium,
    /// Rays per pixel and axis.
    samples: u32,
    width: u32,
    height: u32,
    /// Row-major; None where the ray cannot leave the port.
    rays: Vec<Option<Ray>>,
}

impl CameraRays {
    /// The rays of camera `camera` of `rig`, `samples` x `samples` per pixel
    /// on a regular grid over its area (see [`CameraGeometry::sampled`]).
    pub fn new(rig: &Rig, camera: usize, samples: u32) -> Result<CameraRays, TwinError> {
        rig.validate()?;
        let cam = rig.cameras.get(camera).ok_or(TwinError::NoSuchCamera {
            index: camera,
            count: rig.cameras.len(),
        })?;
        if !(1..=MAX_PIXEL_SAMPLES).contains(&samples) {
            return Err(TwinError::BadParameter {
                name: "pixel samples per axis",
                value: f64::from(samples),
                why: "must be 1..=16",
            });
        }
        let (w, h) = (
            cam.model.intrinsics.width * samples,
            cam.model.intrinsics.height * samples,
        );
        let k = f64::from(samples);
        let rays = (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let yc = (f64::from(y) + 0.5) / k - 0.5;
                (0..w).map(move |x| camera_ray(rig, camera, (f64::from(x) + 0.5) / k - 0.5, yc))
            })
            .collect();
        Ok(CameraRays {
            camera,
            model: cam.model.clone(),
            medium: rig.medium,
            samples,
            width: w,
            height: h,
            rays,
        })
    }

    /// Rays per pixel and axis.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Refuses a rig whose camera or medium differs from the one the rays
    /// were computed for.
    fn check_rig(&self, rig: &Rig) -> Result<(), TwinError> {
        let same = rig
            .cameras
            .get(self.camera)
            .is_some_and(|c| c.model == self.model)
            && rig.medium == self.medium;
        if same {
            Ok(())
        } else {
            Err(TwinError::BadParameter {
                name: "camera rays",
                value: self.camera as f64,
                why: "were computed for another camera or medium than this rig's",
            })
        }
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

/// The poses of a camera and of every projector of its rig, as [`Frame`]s
/// for the per-pixel transforms.
struct DeviceFrames {
    camera: Frame,
    projectors: Vec<Frame>,
}

impl DeviceFrames {
    fn new(rig: &Rig, camera: usize) -> DeviceFrames {
        DeviceFrames {
            camera: Frame::new(&rig.cameras[camera].model.world_from_device),
            projectors: rig
                .projectors
                .iter()
                .map(|p| Frame::new(&p.model.world_from_device))
                .collect(),
        }
    }
}

/// Fills pixels `x0 .. x0 + rays.len()` (at most [`PACKET`]) of `row`: what
/// each camera ray hits and how each projector lights it. Neighbouring
/// pixels' rays, and their shadow rays toward one projector, are cast as one
/// packet (see `mesh::packet`); every pixel gets what it would get alone.
/// `frames`: the rig's device poses ([`DeviceFrames`]).
fn pixels(
    scene: &PosedScene,
    rig: &Rig,
    frames: &DeviceFrames,
    rays: &[Option<Ray>],
    row: &mut RowOut,
    x0: usize,
) {
    let direct = scene.scene().ambient_direct.map(|a| a as f32);
    // Lanes: the pixels that have a ray.
    let mut cast = [Ray::IDLE; PACKET];
    let mut lane_x = [0usize; PACKET];
    let mut n = 0;
    for (i, ray) in rays.iter().enumerate() {
        match ray {
            Some(ray) => {
                (cast[n], lane_x[n]) = (*ray, x0 + i);
                n += 1;
            }
            None => miss(row, x0 + i, direct),
        }
    }
    let hits = scene.intersect_packet(&cast[..n], 0.0, f64::INFINITY);
    let mut surfaces: [Option<Surface>; PACKET] = [const { None }; PACKET];
    for l in 0..n {
        match hits[l] {
            Some(hit) => {
                let s = surface(scene, rig, frames, &cast[l], hit);
                s.write(row, lane_x[l]);
                surfaces[l] = Some(s);
            }
            None => miss(row, lane_x[l], direct),
        }
    }
    for (pi, (pr, frame)) in rig.projectors.iter().zip(&frames.projectors).enumerate() {
        // Lights known without a shadow test go straight in; the rest wait
        // for one packet of shadow rays.
        let mut waiting: [Option<(usize, ShadowTest)>; PACKET] = [None; PACKET];
        let (mut from, mut to) = ([V3::zeros(); PACKET], [V3::zeros(); PACKET]);
        let mut m = 0;
        for l in 0..n {
            let Some(s) = &surfaces[l] else { continue };
            match toward(pr, frame, &rig.medium, s) {
                Light::Known(state) => row.proj[pi].set(lane_x[l], state),
                Light::ShadowTest(test) => {
                    (from[m], to[m]) = (test.start, test.aim);
                    waiting[m] = Some((l, test));
                    m += 1;
                }
            }
        }
        let blocked = scene.occluded_packet(&from[..m], &to[..m]);
        for (k, w) in waiting.iter().take(m).enumerate() {
            let Some((l, test)) = w else { continue };
            let Some(s) = &surfaces[*l] else { continue };
            let state = if blocked[k] {
                (test.uv, [0.0; 3], Illum::Shadowed)
            } else {
                lit(pr, &rig.medium, s, test)
            };
            row.proj[pi].set(lane_x[*l], state);
        }
    }
}

/// Pixel `x` of `row` sees nothing.
fn miss(row: &mut RowOut, x: usize, direct: [f32; 3]) {
    row.depth[x] = f32::NAN;
    row.point[x] = NAN3;
    row.normal[x] = NAN3;
    row.object[x] = u16::MAX;
    row.ambient[x] = direct;
    row.water[x] = 0.0;
    row.proj
        .iter_mut()
        .for_each(|p| p.set(x, (NAN2, [0.0; 3], Illum::NoSurface)));
}

/// What a camera ray hit, with what its projectors' light needs.
struct Surface<'s> {
    hit: Hit,
    material: &'s Material,
    albedo: [f32; 3],
    /// Unit vector from the point toward the camera (its port in water).
    v: V3,
    /// Camera-side water path, metres (0 in air).
    water_c: f64,
    /// z in the camera frame, metres.
    depth_m: f64,
    ambient: [f32; 3],
}

/// The surface a camera ray `ray` meets at `hit` (`frames`: its rig's).
fn surface<'s>(
    scene: &'s PosedScene,
    rig: &Rig,
    frames: &DeviceFrames,
    ray: &Ray,
    hit: Hit,
) -> Surface<'s> {
    let s = scene.scene();
    let direct = s.ambient_direct.map(|a| a as f32);
    let p_cam = frames.camera.point_to_local(&hit.point_m);
    let material = &s.objects[hit.object].material;
    let albedo = material.albedo.at(&hit.local_m);
    let (water_c, view_to) = match rig.medium {
        Medium::Air => (0.0, frames.camera.origin()),
        Medium::Water(_) => (hit.t_m, ray.origin),
    };
    let v = (view_to - hit.point_m).normalize();
    // Surface ambient reaches the camera through the camera-side water path.
    let cam_trans = match &rig.medium {
        Medium::Air => [1.0; 3],
        Medium::Water(wtr) => wtr.transmittance(water_c),
    };
    let ambient = [0, 1, 2].map(|b| {
        let on_surface = s.ambient_surface[b] + material.ambient[b] as f64;
        albedo[b] * (on_surface * cam_trans[b]) as f32 + direct[b]
    });
    Surface {
        hit,
        material,
        albedo,
        v,
        water_c,
        depth_m: p_cam.z,
        ambient,
    }
}

impl Surface<'_> {
    /// The camera's own outputs at pixel `x`.
    fn write(&self, row: &mut RowOut, x: usize) {
        row.depth[x] = self.depth_m as f32;
        row.point[x] = f3(&self.hit.point_m);
        row.normal[x] = f3(&self.hit.normal);
        row.object[x] = self.hit.object as u16;
        row.ambient[x] = self.ambient;
        row.water[x] = self.water_c as f32;
    }
}

/// One projector's light on a surface point: known at once (off the DMD,
/// facing away), or waiting for the shadow ray toward the projector.
enum Light {
    Known(([f32; 2], [f32; 3], Illum)),
    ShadowTest(ShadowTest),
}

/// A lit-unless-shadowed point, with what its shading needs.
#[derive(Clone, Copy)]
struct ShadowTest {
    uv: [f32; 2],
    /// Shadow ray from just off the surface to where the light leaves the projector.
    start: V3,
    aim: V3,
    /// Unit vector toward the projector and its cosine with the normal.
    l: V3,
    cos_i: f64,
    /// Distance from the projector's centre, metres.
    dist_m: f64,
    /// Projector-side water path, metres.
    water_p: f64,
}

/// Where projector `pr`'s light (`frame`: its pose) meets surface `s`, up
/// to the shadow test.
fn toward(pr: &Projector, frame: &Frame, medium: &Medium, s: &Surface) -> Light {
    let hit = &s.hit;
    let model = &pr.model;
    let q = frame.point_to_local(&hit.point_m);
    // Where the light leaves the device: its centre, or its port crossing in water.
    let (aim_local, water_p) = match medium {
        Medium::Air => (Some(V3::zeros()), 0.0),
        Medium::Water(wtr) => match wtr.port_crossing(&q) {
            Some(c) => (Some(c), (q - c).norm()),
            None => (None, 0.0),
        },
    };
    let Some(aim_local) = aim_local else {
        return Light::Known((NAN2, [0.0; 3], Illum::OutsideDmd));
    };
    let dir_local = if aim_local.norm() > 0.0 { aim_local } else { q };
    let Some(uv) = model.project_local(&dir_local) else {
        return Light::Known((NAN2, [0.0; 3], Illum::OutsideDmd));
    };
    let uv32 = [uv[0] as f32, uv[1] as f32];
    if !model.contains(uv) {
        return Light::Known((uv32, [0.0; 3], Illum::OutsideDmd));
    }
    let aim = frame.point_to_world(&aim_local);
    let l = (aim - hit.point_m).normalize();
    let cos_i = hit.normal.dot(&l);
    if cos_i <= 0.0 || hit.normal.dot(&s.v) <= 0.0 {
        return Light::Known((uv32, [0.0; 3], Illum::BackFacing));
    }
    Light::ShadowTest(ShadowTest {
        uv: uv32,
        // Start the shadow ray just off the surface to avoid self-hits.
        start: hit.point_m + hit.normal * 1e-6,
        aim,
        l,
        cos_i,
        dist_m: q.norm(),
        water_p,
    })
}

/// Projector `pr`'s gain on surface `s` where the shadow ray `t` got through.
fn lit(
    pr: &Projector,
    medium: &Medium,
    s: &Surface,
    t: &ShadowTest,
) -> ([f32; 2], [f32; 3], Illum) {
    let falloff = (pr.reference_distance_m / t.dist_m).powi(2);
    let half = (t.l + s.v).normalize();
    let spec = if s.material.specular > 0.0 {
        s.material.specular as f64
            * s.hit
                .normal
                .dot(&half)
                .max(0.0)
                .powf(s.material.shininess as f64)
    } else {
        0.0
    };
    let trans = match medium {
        Medium::Air => [1.0; 3],
        Medium::Water(wtr) => wtr.transmittance(t.water_p + s.water_c),
    };
    let gain = [0, 1, 2].map(|b| {
        (pr.led_power[b] * falloff * (s.albedo[b] as f64 * t.cos_i + spec) * trans[b]) as f32
    });
    (t.uv, gain, Illum::Lit)
}
