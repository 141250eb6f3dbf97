//! Scenes: objects (shape + material + pose + motion) and the ambient light.

use nalgebra::{Point3, Translation3, Unit, UnitQuaternion};
use std::sync::Arc;

use super::error::{non_negative, positive, TwinError};
use super::geometry::{Frame, LocalHit, Pose, Ray, Shape, V3};
use super::mesh::PACKET;

/// An RGB texture mapped onto the local x-y plane of its object.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Row-major RGB reflectances in [0, 1].
    pub rgb: Vec<[f32; 3]>,
    /// Size the texture covers, metres (x, y), centred on the local origin.
    pub size_m: [f64; 2],
}

/// Diffuse reflectance per LED band (R, G, B), constant or varying over the surface.
#[derive(Clone, Debug)]
pub enum Albedo {
    /// The same everywhere.
    Constant([f32; 3]),
    /// A checkerboard on the local x-y plane (see [`Checkerboard`]), white margin outside.
    Checker(Checkerboard),
    /// Planar texture on the local x-y plane (nearest texel), edge texels repeat.
    Texture(Arc<Texture>),
    /// Colour sectors by azimuth about the local z axis (multi-coloured objects).
    Sectors(Vec<[f32; 3]>),
    /// Stripes along local x of `period_m`, cycling through the listed colours
    /// (e.g. a 50:1 reflectivity range on a metal part).
    Stripes {
        /// Stripe width, metres.
        period_m: f64,
        /// Reflectances cycled through.
        colours: Vec<[f32; 3]>,
    },
}

impl Albedo {
    /// Reflectance at a local surface point.
    pub fn at(&self, p_local: &V3) -> [f32; 3] {
        match self {
            Albedo::Constant(c) => *c,
            Albedo::Checker(board) => board.albedo_at(p_local.x, p_local.y),
            Albedo::Texture(t) => {
                let u = (p_local.x / t.size_m[0] + 0.5) * t.width as f64;
                let v = (p_local.y / t.size_m[1] + 0.5) * t.height as f64;
                let i = (u.floor().max(0.0) as u32).min(t.width - 1);
                let j = (v.floor().max(0.0) as u32).min(t.height - 1);
                t.rgb[(j * t.width + i) as usize]
            }
            Albedo::Sectors(cs) => {
                let a = p_local.y.atan2(p_local.x) + std::f64::consts::PI;
                let k = ((a / std::f64::consts::TAU) * cs.len() as f64) as usize;
                cs[k.min(cs.len() - 1)]
            }
            Albedo::Stripes { period_m, colours } => {
                let k = (p_local.x / period_m)
                    .floor()
                    .rem_euclid(colours.len() as f64) as usize;
                colours[k.min(colours.len() - 1)]
            }
        }
    }
}

/// A printed planar checkerboard calibration target in its object's local
/// x-y plane, centred on the origin. Square (i, j) (i along x, j along y,
/// from the -x -y corner) is dark when i + j is even.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checkerboard {
    /// Squares along x.
    pub squares_x: u32,
    /// Squares along y.
    pub squares_y: u32,
    /// Side of one square, metres.
    pub square_m: f64,
    /// Reflectance of the dark squares.
    pub dark: f32,
    /// Reflectance of the light squares and the margin.
    pub light: f32,
}

impl Checkerboard {
    fn albedo_at(&self, x: f64, y: f64) -> [f32; 3] {
        let u = x / self.square_m + 0.5 * self.squares_x as f64;
        let v = y / self.square_m + 0.5 * self.squares_y as f64;
        let inside = u >= 0.0 && v >= 0.0 && u < self.squares_x as f64 && v < self.squares_y as f64;
        let dark = inside && (u.floor() as i64 + v.floor() as i64) % 2 == 0;
        [if dark { self.dark } else { self.light }; 3]
    }

    /// Inner corners in the local frame, row by row (y), x fastest:
    /// (squares_x - 1) * (squares_y - 1) points, the order OpenCV reports them in.
    pub fn inner_corners_local(&self) -> Vec<V3> {
        let mut out = Vec::new();
        for j in 1..self.squares_y {
            for i in 1..self.squares_x {
                let x = (i as f64 - 0.5 * self.squares_x as f64) * self.square_m;
                let y = (j as f64 - 0.5 * self.squares_y as f64) * self.square_m;
                out.push(V3::new(x, y, 0.0));
            }
        }
        out
    }

    /// Pixel positions (with lens distortion) of the inner corners when the
    /// board sits at `pose`, in [`Self::inner_corners_local`] order; None
    /// for corners behind the camera. The truth the calibration tests use.
    pub fn corners_px(
        &self,
        pose: &Pose,
        camera: &super::device::Pinhole,
    ) -> Vec<Option<[f64; 2]>> {
        self.inner_corners_local()
            .iter()
            .map(|c| camera.project(&pose.transform_point(&Point3::from(*c)).coords))
            .collect()
    }

    /// The board as a scene object at `pose`, with a one-square white margin.
    pub fn object(&self, pose: Pose) -> Object {
        Object::new(
            "checkerboard",
            Shape::Rect {
                half_x_m: 0.5 * (self.squares_x + 2) as f64 * self.square_m,
                half_y_m: 0.5 * (self.squares_y + 2) as f64 * self.square_m,
            },
            Material::matte(Albedo::Checker(*self)),
            pose,
        )
    }
}

/// Surface reflectance: a diffuse albedo plus a Blinn-Phong specular lobe.
#[derive(Clone, Debug)]
pub struct Material {
    /// Diffuse reflectance per LED band.
    pub albedo: Albedo,
    /// Specular peak relative to a white diffuser (values >> 1 saturate the sensor).
    pub specular: f32,
    /// Blinn-Phong exponent of the lobe.
    pub shininess: f32,
    /// Flat extra irradiance on this surface per band, twin units/s
    /// (light from neighbouring surfaces, seed 003's per-patch Li).
    pub ambient: [f32; 3],
}

impl Material {
    /// A purely diffuse material.
    pub fn matte(albedo: Albedo) -> Material {
        Material {
            albedo,
            specular: 0.0,
            shininess: 1.0,
            ambient: [0.0; 3],
        }
    }
}

/// How an object moves; `pose_at(t)` composes the motion onto the rest pose.
#[derive(Clone, Copy, Debug, Default)]
pub enum Motion {
    /// Never moves.
    #[default]
    Static,
    /// Spins about a world axis through a world point (rotating fan).
    Spin {
        /// A point on the axis, metres.
        centre_m: V3,
        /// Axis direction (normalised on use).
        axis: V3,
        /// Angular rate, rad/s.
        rate_rad_s: f64,
    },
    /// Moves with constant acceleration from an initial velocity (falling object).
    Ballistic {
        /// Velocity at t = 0, m/s.
        velocity_m_s: V3,
        /// Acceleration, m/s^2 (gravity).
        accel_m_s2: V3,
    },
}

/// One object of a scene.
#[derive(Clone, Debug)]
pub struct Object {
    /// Name used in the ground-truth object-id legend.
    pub name: String,
    /// Geometry in the local frame.
    pub shape: Shape,
    /// Surface reflectance.
    pub material: Material,
    /// Pose `world_from_local` at t = 0.
    pub pose: Pose,
    /// Motion over time.
    pub motion: Motion,
}

impl Object {
    /// A static object.
    pub fn new(name: &str, shape: Shape, material: Material, pose: Pose) -> Object {
        Object {
            name: name.to_string(),
            shape,
            material,
            pose,
            motion: Motion::Static,
        }
    }

    /// Pose at time `t_s`.
    pub fn pose_at(&self, t_s: f64) -> Pose {
        match self.motion {
            Motion::Static => self.pose,
            Motion::Spin {
                centre_m,
                axis,
                rate_rad_s,
            } => {
                let rot =
                    UnitQuaternion::from_axis_angle(&Unit::new_normalize(axis), rate_rad_s * t_s);
                let about = Translation3::from(centre_m) * rot * Translation3::from(-centre_m);
                about * self.pose
            }
            Motion::Ballistic {
                velocity_m_s,
                accel_m_s2,
            } => Translation3::from(velocity_m_s * t_s + 0.5 * accel_m_s2 * t_s * t_s) * self.pose,
        }
    }
}

/// A world hit: which object, where, its normal and its local point.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    /// Index of the object in the scene.
    pub object: usize,
    /// Distance along the ray, metres.
    pub t_m: f64,
    /// World point, metres.
    pub point_m: V3,
    /// World unit normal facing the ray.
    pub normal: V3,
    /// The point in the object's local frame (for textures).
    pub local_m: V3,
}

/// Objects and ambient light.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// The objects.
    pub objects: Vec<Object>,
    /// Ambient irradiance on every surface per LED band, twin units/s (seed 003's Li).
    pub ambient_surface: [f64; 3],
    /// Stray light reaching the sensor directly per band, twin units/s (seed 003's La).
    pub ambient_direct: [f64; 3],
}

/// The objects of a scene frozen at one instant (poses resolved).
#[derive(Clone, Debug)]
pub struct PosedScene<'a> {
    scene: &'a Scene,
    /// Per object, its pose as a [`Frame`]: every ray is moved into every
    /// object's frame, and every hit back.
    frames: Vec<Frame>,
}

impl PosedScene<'_> {
    fn ray_to_local(&self, i: usize, ray: &Ray) -> Ray {
        let frame = &self.frames[i];
        Ray {
            origin: frame.point_to_local(&ray.origin),
            dir: frame.vector_to_local(&ray.dir),
        }
    }
}

impl Albedo {
    /// Rejects empty colour lists, textures whose buffer does not match
    /// their size, and non-positive sizes.
    pub fn validate(&self) -> Result<(), TwinError> {
        match self {
            Albedo::Constant(_) => Ok(()),
            Albedo::Checker(b) => {
                positive("checker square_m", b.square_m)?;
                positive("checker squares", (b.squares_x.min(b.squares_y)) as f64)?;
                Ok(())
            }
            Albedo::Texture(t) => {
                positive("texture width", t.width as f64)?;
                positive("texture height", t.height as f64)?;
                positive("texture size_m", t.size_m[0].min(t.size_m[1]))?;
                if t.rgb.len() != t.width as usize * t.height as usize {
                    return Err(TwinError::BadParameter {
                        name: "texture texels",
                        value: t.rgb.len() as f64,
                        why: "must be width * height",
                    });
                }
                Ok(())
            }
            Albedo::Sectors(cs) => positive("sector colours", cs.len() as f64).map(|_| ()),
            Albedo::Stripes { period_m, colours } => {
                positive("stripe period_m", *period_m)?;
                positive("stripe colours", colours.len() as f64).map(|_| ())
            }
        }
    }
}

impl Shape {
    /// Rejects non-positive or non-finite sizes.
    pub fn validate(&self) -> Result<(), TwinError> {
        match self {
            Shape::Rect { half_x_m, half_y_m } => {
                positive("rect half size", half_x_m.min(*half_y_m)).map(|_| ())
            }
            Shape::Sphere { radius_m } => positive("sphere radius_m", *radius_m).map(|_| ()),
            Shape::Cuboid { half_m } => positive("cuboid half size", half_m.min()).map(|_| ()),
            Shape::Mesh(_) => Ok(()), // validated when built
        }
    }
}

impl Scene {
    /// Checks every object (shape, albedo, finite pose and motion) and the
    /// ambient terms; the renderer calls it before casting rays.
    pub fn validate(&self) -> Result<(), TwinError> {
        if self.objects.len() >= u16::MAX as usize {
            return Err(TwinError::BadParameter {
                name: "object count",
                value: self.objects.len() as f64,
                why: "must be < 65535",
            });
        }
        for o in &self.objects {
            o.shape.validate()?;
            o.material.albedo.validate()?;
            let p = o.pose.to_homogeneous();
            let motion_ok = match o.motion {
                Motion::Static => true,
                Motion::Spin {
                    centre_m,
                    axis,
                    rate_rad_s,
                } => {
                    centre_m.iter().all(|c| c.is_finite())
                        && axis.norm() > 0.0
                        && axis.iter().all(|c| c.is_finite())
                        && rate_rad_s.is_finite()
                }
                Motion::Ballistic {
                    velocity_m_s,
                    accel_m_s2,
                } => velocity_m_s
                    .iter()
                    .chain(accel_m_s2.iter())
                    .all(|c| c.is_finite()),
            };
            if !p.iter().all(|c| c.is_finite()) || !motion_ok {
                return Err(TwinError::BadParameter {
                    name: "object pose/motion",
                    value: f64::NAN,
                    why: "must be finite (and a spin axis non-zero)",
                });
            }
            non_negative("material specular", o.material.specular as f64)?;
            for a in o.material.ambient {
                non_negative("material ambient", a as f64)?;
            }
        }
        for a in self.ambient_surface.iter().chain(&self.ambient_direct) {
            non_negative("scene ambient", *a)?;
        }
        Ok(())
    }

    /// Whether any object moves.
    pub fn is_dynamic(&self) -> bool {
        self.objects
            .iter()
            .any(|o| !matches!(o.motion, Motion::Static))
    }

    /// The scene frozen at time `t_s`.
    pub fn at(&self, t_s: f64) -> PosedScene<'_> {
        let frames = self
            .objects
            .iter()
            .map(|o| Frame::new(&o.pose_at(t_s)))
            .collect();
        PosedScene {
            scene: self,
            frames,
        }
    }
}

impl PosedScene<'_> {
    /// The underlying scene.
    pub fn scene(&self) -> &Scene {
        self.scene
    }

    /// Nearest hit with `t_min < t < t_max` over all objects.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<Hit> {
        let mut best: Option<(usize, LocalHit, Ray)> = None;
        let mut t_best = t_max;
        for (i, obj) in self.scene.objects.iter().enumerate() {
            let local = self.ray_to_local(i, ray);
            if let Some(h) = obj.shape.intersect(&local, t_min, t_best) {
                t_best = h.t_m;
                best = Some((i, h, local));
            }
        }
        let (i, h, local) = best?;
        Some(self.world_hit(i, h, &local))
    }

    /// [`Self::intersect`] of up to [`PACKET`] rays at once (each from `t_min`
    /// to `t_max`): a mesh walks its BVH once for all of them. Lanes past
    /// `rays.len()` are None.
    pub fn intersect_packet(&self, rays: &[Ray], t_min: f64, t_max: f64) -> [Option<Hit>; PACKET] {
        let n = rays.len();
        assert!(n <= PACKET, "{n} rays in a packet of {PACKET}");
        // Plain loops over arrays made once: `array::map` / `from_fn` of these
        // structs cost a copy of the whole array each.
        let mut nearest = [None::<(usize, LocalHit)>; PACKET];
        let mut nearest_local = [Ray::IDLE; PACKET];
        let mut local = [Ray::IDLE; PACKET];
        let mut t_best = [t_max; PACKET];
        for (i, obj) in self.scene.objects.iter().enumerate() {
            for l in 0..n {
                local[l] = self.ray_to_local(i, &rays[l]);
            }
            let hits = obj.shape.intersect_packet(&local[..n], t_min, &t_best[..n]);
            for l in 0..n {
                if let Some(h) = hits[l] {
                    t_best[l] = h.t_m;
                    nearest[l] = Some((i, h));
                    nearest_local[l] = local[l];
                }
            }
        }
        let mut out = [None; PACKET];
        for l in 0..n {
            if let Some((i, h)) = nearest[l] {
                out[l] = Some(self.world_hit(i, h, &nearest_local[l]));
            }
        }
        out
    }

    /// Object `i`'s local hit `h` of the local ray `local`, in the world.
    fn world_hit(&self, i: usize, h: LocalHit, local: &Ray) -> Hit {
        let frame = &self.frames[i];
        let local_m = local.at(h.t_m);
        Hit {
            object: i,
            t_m: h.t_m,
            point_m: frame.point_to_world(&local_m),
            normal: frame.vector_to_world(&h.normal),
            local_m,
        }
    }

    /// Whether anything blocks the segment from `from_m` to `to_m`
    /// (ends excluded by a small relative margin).
    pub fn occluded(&self, from_m: &V3, to_m: &V3) -> bool {
        let (ray, t_min, t_max) = segment(from_m, to_m);
        self.scene
            .objects
            .iter()
            .enumerate()
            .any(|(i, o)| o.shape.occludes(&self.ray_to_local(i, &ray), t_min, t_max))
    }

    /// [`Self::occluded`] of up to [`PACKET`] segments at once (lane `l`: from
    /// `from_m[l]` to `to_m[l]`); lanes past `from_m.len()` are false.
    pub fn occluded_packet(&self, from_m: &[V3], to_m: &[V3]) -> [bool; PACKET] {
        let n = from_m.len();
        assert!(
            n <= PACKET && to_m.len() == n,
            "{n} segments in a packet of {PACKET}"
        );
        let mut blocked = [false; PACKET];
        // The same ray and margins as the one-segment query, lane by lane.
        let mut ray = [Ray::IDLE; PACKET];
        let (mut t_min, mut t_end) = ([0.0; PACKET], [0.0; PACKET]);
        for l in 0..n {
            (ray[l], t_min[l], t_end[l]) = segment(&from_m[l], &to_m[l]);
        }
        let mut local = [Ray::IDLE; PACKET];
        let mut t_max = [0.0; PACKET];
        for (i, o) in self.scene.objects.iter().enumerate() {
            if blocked[..n].iter().all(|&b| b) {
                break;
            }
            for l in 0..n {
                local[l] = self.ray_to_local(i, &ray[l]);
                // A lane already blocked needs no more tests: an empty interval.
                t_max[l] = if blocked[l] {
                    f64::NEG_INFINITY
                } else {
                    t_end[l]
                };
            }
            let hit = o
                .shape
                .occludes_packet(&local[..n], &t_min[..n], &t_max[..n]);
            for l in 0..n {
                blocked[l] |= hit[l];
            }
        }
        blocked
    }
}

/// The ray from `from_m` toward `to_m` and the interval of it an occluder
/// must lie in: the segment less a small margin at each end, relative to the
/// start's distance from the origin (so a surface does not shadow itself).
fn segment(from_m: &V3, to_m: &V3) -> (Ray, f64, f64) {
    let d = to_m - from_m;
    let len = d.norm();
    let eps = 1e-7 * (1.0 + from_m.norm());
    let ray = Ray {
        origin: *from_m,
        dir: d / len,
    };
    (ray, eps, len - eps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checker_corners_count_and_colour() {
        let b = Checkerboard {
            squares_x: 9,
            squares_y: 6,
            square_m: 0.02,
            dark: 0.05,
            light: 0.9,
        };
        assert_eq!(b.inner_corners_local().len(), 8 * 5);
        // Centre of the -x -y square is dark, its right neighbour light.
        let x0 = -4.0 * 0.02;
        let y0 = -2.5 * 0.02;
        assert_eq!(b.albedo_at(x0, y0)[0], 0.05);
        assert_eq!(b.albedo_at(x0 + 0.02, y0)[0], 0.9);
    }

    #[test]
    fn spin_moves_points_on_a_circle() {
        let mut o = Object::new(
            "b",
            Shape::Sphere { radius_m: 0.01 },
            Material::matte(Albedo::Constant([1.0; 3])),
            Pose::translation(0.1, 0.0, 0.0),
        );
        o.motion = Motion::Spin {
            centre_m: V3::zeros(),
            axis: V3::z(),
            rate_rad_s: std::f64::consts::PI,
        };
        let p = o.pose_at(0.5).translation.vector;
        assert!((p - V3::new(0.0, 0.1, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn bad_scenes_are_errors_not_panics() {
        let ok = Object::new(
            "s",
            Shape::Sphere { radius_m: 0.1 },
            Material::matte(Albedo::Constant([1.0; 3])),
            Pose::identity(),
        );
        let mut s = Scene {
            objects: vec![ok.clone()],
            ..Default::default()
        };
        assert!(s.validate().is_ok());
        s.objects[0].material.albedo = Albedo::Sectors(vec![]);
        assert!(s.validate().is_err());
        s.objects[0] = Object::new(
            "s",
            Shape::Sphere { radius_m: f64::NAN },
            ok.material.clone(),
            Pose::identity(),
        );
        assert!(s.validate().is_err());
        s.objects[0] = Object::new(
            "s",
            Shape::Sphere { radius_m: 0.1 },
            ok.material.clone(),
            Pose::translation(f64::NAN, 0.0, 0.0),
        );
        assert!(s.validate().is_err());
    }

    #[test]
    fn occlusion_between_points() {
        let s = Scene {
            objects: vec![Object::new(
                "s",
                Shape::Sphere { radius_m: 0.1 },
                Material::matte(Albedo::Constant([1.0; 3])),
                Pose::identity(),
            )],
            ..Default::default()
        };
        let posed = s.at(0.0);
        assert!(posed.occluded(&V3::new(-1.0, 0.0, 0.0), &V3::new(1.0, 0.0, 0.0)));
        assert!(!posed.occluded(&V3::new(-1.0, 0.5, 0.0), &V3::new(1.0, 0.5, 0.0)));
    }
}
