//! Conversions between the reconstruction's `f32` clouds and fusion's
//! `f64` clouds, and rigid moves of a cloud.

use nalgebra::{Isometry3, Vector3};

use crate::fusion;
use crate::point_cloud::PointCloud;

/// A reconstruction cloud as fusion's (normals left to fusion's PCA).
pub(crate) fn to_fusion(cloud: &PointCloud) -> fusion::PointCloud {
    fusion::PointCloud {
        points: cloud
            .points_m
            .iter()
            .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .collect(),
        normals: None,
        quality: cloud.quality_m.clone(),
    }
}

/// A fused cloud for the PLY writer.
pub fn from_fusion(cloud: &fusion::PointCloud) -> PointCloud {
    PointCloud {
        points_m: cloud
            .points
            .iter()
            .map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect(),
        normals: cloud.normals.as_ref().map(|n| {
            n.iter()
                .map(|v| [v.x as f32, v.y as f32, v.z as f32])
                .collect()
        }),
        colours: None,
        quality_m: cloud.quality.clone(),
    }
}

/// The fused cloud with the heads' normals and colours, which the merge
/// does not carry: its points are A's in order, then B's `b_kept` (`b_in_a`
/// already moved into A's frame). An attribute one head lacks is left out.
pub(crate) fn with_head_attributes(
    mut fused: PointCloud,
    a: &PointCloud,
    b_in_a: &PointCloud,
    b_kept: &[usize],
) -> PointCloud {
    fn join<T: Copy>(a: Option<&Vec<T>>, b: Option<&Vec<T>>, kept: &[usize]) -> Option<Vec<T>> {
        let (a, b) = (a?, b?);
        Some(
            a.iter()
                .copied()
                .chain(kept.iter().map(|&i| b[i]))
                .collect(),
        )
    }
    if fused.len() == a.len() + b_kept.len() {
        fused.normals = join(a.normals.as_ref(), b_in_a.normals.as_ref(), b_kept);
        fused.colours = join(a.colours.as_ref(), b_in_a.colours.as_ref(), b_kept);
    }
    fused
}

/// Points as `f64` vectors.
pub(crate) fn points_f64(cloud: &PointCloud) -> Vec<Vector3<f64>> {
    cloud
        .points_m
        .iter()
        .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect()
}

/// The cloud moved by `t` (normals rotated).
pub(crate) fn transformed(cloud: &PointCloud, t: &Isometry3<f64>) -> PointCloud {
    let map = |p: &[f32; 3]| {
        let q = t * nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        [q.x as f32, q.y as f32, q.z as f32]
    };
    let rot = |n: &[f32; 3]| {
        let v = t.rotation * Vector3::new(n[0] as f64, n[1] as f64, n[2] as f64);
        [v.x as f32, v.y as f32, v.z as f32]
    };
    PointCloud {
        points_m: cloud.points_m.iter().map(map).collect(),
        normals: cloud
            .normals
            .as_ref()
            .map(|ns| ns.iter().map(rot).collect()),
        colours: cloud.colours.clone(),
        quality_m: cloud.quality_m.clone(),
    }
}
