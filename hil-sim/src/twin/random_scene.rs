//! Random scenes for training sets: a few primitives and height fields in
//! front of a wall, drawn from a seeded generator so every sample can be
//! rebuilt from (seed, index).

use std::sync::Arc;

use rand::Rng;

use super::error::TwinError;
use super::geometry::{Pose, Shape, V3};
use super::mesh::Mesh;
use super::scene::{Albedo, Material, Object, Scene};

/// Where random objects go: a box in the world, metres.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    /// x range of object centres.
    pub x_m: (f64, f64),
    /// y range of object centres.
    pub y_m: (f64, f64),
    /// z range of object centres.
    pub z_m: (f64, f64),
    /// z of the background wall.
    pub wall_z_m: f64,
}

/// Draws 1..=4 objects (spheres, boxes, wavy height fields) in `place`,
/// grey (`colour` false) or coloured albedo, some glossy.
pub fn random_scene(
    rng: &mut impl Rng,
    place: &Placement,
    colour: bool,
) -> Result<Scene, TwinError> {
    let n = rng.random_range(1..=4);
    let mut objects = Vec::with_capacity(n + 1);
    for i in 0..n {
        let centre = V3::new(
            rng.random_range(place.x_m.0..place.x_m.1),
            rng.random_range(place.y_m.0..place.y_m.1),
            rng.random_range(place.z_m.0..place.z_m.1),
        );
        let angles = V3::new(
            rng.random_range(-0.6..0.6),
            rng.random_range(-0.6..0.6),
            rng.random_range(-3.1..3.1),
        );
        let pose = Pose::new(centre, angles);
        let shape = match rng.random_range(0..3) {
            0 => Shape::Sphere {
                radius_m: rng.random_range(0.015..0.06),
            },
            1 => Shape::Cuboid {
                half_m: V3::new(
                    rng.random_range(0.01..0.05),
                    rng.random_range(0.01..0.05),
                    rng.random_range(0.01..0.04),
                ),
            },
            _ => {
                let (a, fx, fy) = (
                    rng.random_range(0.003..0.015),
                    rng.random_range(10.0..60.0),
                    rng.random_range(10.0..60.0),
                );
                let size = rng.random_range(0.06..0.16);
                Shape::Mesh(Arc::new(Mesh::height_field(
                    64,
                    64,
                    size,
                    size,
                    move |x, y| a * (fx * x).sin() * (fy * y).cos(),
                )?))
            }
        };
        let albedo = if colour {
            [
                rng.random_range(0.05..0.9),
                rng.random_range(0.05..0.9),
                rng.random_range(0.05..0.9),
            ]
        } else {
            [rng.random_range(0.2..0.9); 3]
        };
        let glossy = rng.random_bool(0.25);
        let material = Material {
            albedo: Albedo::Constant(albedo),
            specular: if glossy {
                rng.random_range(0.5..4.0)
            } else {
                0.0
            },
            shininess: rng.random_range(40.0..400.0),
            ambient: [0.0; 3],
        };
        objects.push(Object::new(&format!("random-{i}"), shape, material, pose));
    }
    let g = rng.random_range(0.2..0.7);
    objects.push(Object::new(
        "wall",
        Shape::Rect {
            half_x_m: 1.5,
            half_y_m: 1.5,
        },
        Material::matte(Albedo::Constant([g; 3])),
        Pose::translation(0.0, 0.0, place.wall_z_m),
    ));
    let amb = rng.random_range(0.0..0.1);
    Ok(Scene {
        objects,
        ambient_surface: [amb; 3],
        ambient_direct: [0.2 * amb; 3],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn same_seed_same_scene() {
        let place = Placement {
            x_m: (-0.1, 0.1),
            y_m: (-0.1, 0.1),
            z_m: (0.45, 0.5),
            wall_z_m: 0.6,
        };
        let names = |s: u64| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s);
            let sc = random_scene(&mut rng, &place, true).unwrap();
            sc.objects
                .iter()
                .map(|o| format!("{:?}", o.pose))
                .collect::<Vec<_>>()
        };
        assert_eq!(names(3), names(3));
        assert_ne!(names(3), names(4));
    }
}
