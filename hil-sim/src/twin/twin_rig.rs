//! A scene and a rig together, as the simulated cameras use them: each
//! camera's ray-cast geometry is built on first use and kept while the
//! scene is static; a moving scene is re-cast per exposure.

use std::sync::{Arc, Mutex};

use rand::Rng;

use super::device::Rig;
use super::error::TwinError;
use super::pattern::{Exposure, ProjectorTimeline};
use super::render::{render_exposure, Frame, Renderer};
use super::scene::Scene;
use super::sensor::{Image, SensorModel};

/// Scene + rig with per-camera cached geometry.
#[derive(Debug)]
pub struct TwinRig {
    scene: Scene,
    rig: Rig,
    renderers: Mutex<Vec<Option<Arc<Renderer>>>>,
}

impl TwinRig {
    /// Checks the rig and holds both; nothing is ray-cast yet.
    pub fn new(scene: Scene, rig: Rig) -> Result<TwinRig, TwinError> {
        rig.validate()?;
        let n = rig.cameras.len();
        Ok(TwinRig {
            scene,
            rig,
            renderers: Mutex::new(vec![None; n]),
        })
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The rig.
    pub fn rig(&self) -> &Rig {
        &self.rig
    }

    /// The cached renderer of a camera of a static scene (built on first use).
    pub fn renderer(&self, camera: usize) -> Result<Arc<Renderer>, TwinError> {
        let count = self.rig.cameras.len();
        if camera >= count {
            return Err(TwinError::NoSuchCamera {
                index: camera,
                count,
            });
        }
        let mut cache = self.renderers.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(r) = &cache[camera] {
            return Ok(r.clone());
        }
        let r = Arc::new(Renderer::new(&self.scene, &self.rig, camera, 0.0)?);
        cache[camera] = Some(r.clone());
        Ok(r)
    }

    /// The noisy image camera `camera` records during `exposure`.
    pub fn image(
        &self,
        camera: usize,
        timelines: &[ProjectorTimeline],
        exposure: Exposure,
        sensor: &SensorModel,
        rng: &mut impl Rng,
    ) -> Result<(Image, Vec<bool>), TwinError> {
        if self.scene.is_dynamic() {
            let f = render_exposure(
                &self.scene,
                &self.rig,
                camera,
                timelines,
                exposure,
                sensor,
                rng,
            )?;
            return Ok((f.image, f.truth.saturated));
        }
        self.renderer(camera)?
            .image(timelines, exposure, sensor, rng.random())
    }

    /// A full frame (images, clean targets, truth) of camera `camera`.
    pub fn frame(
        &self,
        camera: usize,
        timelines: &[ProjectorTimeline],
        exposure: Exposure,
        sensor: &SensorModel,
        rng: &mut impl Rng,
    ) -> Result<Frame, TwinError> {
        if self.scene.is_dynamic() {
            return render_exposure(
                &self.scene,
                &self.rig,
                camera,
                timelines,
                exposure,
                sensor,
                rng,
            );
        }
        self.renderer(camera)?
            .frame(timelines, exposure, sensor, rng.random())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::scenes::{built_in, Detail};
    use crate::twin::Pattern;
    use rand::SeedableRng;

    #[test]
    fn static_scene_is_cast_once_and_matches_a_fresh_render() {
        let detail = Detail {
            camera: (40, 30),
            projector: (50, 30),
        };
        let (scene, rig) = built_in("large-part", &detail).unwrap();
        let twin = TwinRig::new(scene.clone(), rig.clone()).unwrap();
        let white = Arc::new(Pattern::flat(50, 30, 1.0));
        let tl = vec![
            ProjectorTimeline::single(white.clone(), 0.0, 1e-3),
            ProjectorTimeline::dark(),
        ];
        let exp = Exposure {
            start_s: 0.0,
            end_s: 1e-3,
        };
        let sensor = SensorModel::mono12();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let a = twin.image(1, &tl, exp, &sensor, &mut rng).unwrap();
        let r1 = twin.renderer(1).unwrap();
        let r2 = twin.renderer(1).unwrap();
        assert!(Arc::ptr_eq(&r1, &r2), "geometry must be cached");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let b = render_exposure(&scene, &rig, 1, &tl, exp, &sensor, &mut rng).unwrap();
        assert_eq!(a.0, b.image);
        assert!(matches!(
            twin.renderer(2),
            Err(TwinError::NoSuchCamera { index: 2, count: 2 })
        ));
    }
}
