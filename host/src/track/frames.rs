//! Where the pairs come from: the [`FrameSource`] interface, and the virtual cameras that
//! render a scene at the posture the head's servos are in.
//!
//! Real cameras ([`super::cameras`], V4L2) implement the same trait.

use anyhow::{anyhow, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::posture::HeadRig;
use hvs_vision::render::RenderOptions;
use hvs_vision::scene::{render_scene, Scene, SceneRender};
use image::GrayImage;

/// One stereo frame.
pub struct Frame {
    /// Left image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
    /// With a virtual scene: the render with its truth (for the log's errors only).
    pub truth: Option<Box<SceneRender>>,
}

/// A source of stereo frames at a posture.
pub trait FrameSource {
    /// The pair at time `t_s` (s since start) with the head at `joints`.
    fn grab(&mut self, t_s: f64, joints: &Joints) -> Result<Frame>;
}

/// The virtual cameras: the scene rendered through the rig at the servos' posture.
pub struct VirtualCameras {
    /// The rig on the head.
    pub head: HeadRig,
    /// The scene.
    pub scene: Scene,
    /// Blur, noise, supersampling.
    pub opt: RenderOptions,
    /// Seed of the sensor noise (frame `k` gets its own stream).
    pub seed: u64,
    frame: u64,
}

impl VirtualCameras {
    /// Cameras of `head` looking at `scene`.
    pub fn new(head: HeadRig, scene: Scene, opt: RenderOptions, seed: u64) -> VirtualCameras {
        VirtualCameras { head, scene, opt, seed, frame: 0 }
    }
}

/// The virtual cameras' image options of the loop (`hvs track`, `hvs view --scene`): the
/// renderer's blur and noise, 4x4 supersampling.
pub fn loop_render_options() -> RenderOptions {
    RenderOptions { supersample: 4, ..RenderOptions::default() }
}

/// splitmix64: one seed per frame from the run's seed.
pub(crate) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl FrameSource for VirtualCameras {
    fn grab(&mut self, t_s: f64, joints: &Joints) -> Result<Frame> {
        let seed = mix(self.seed ^ mix(self.frame));
        self.frame += 1;
        let r = render_scene(&self.head, joints, &self.scene.at(t_s), &self.opt, seed)
            .map_err(|e| anyhow!("virtual cameras: {e}"))?;
        Ok(Frame { left: r.left.clone(), right: r.right.clone(), truth: Some(Box::new(r)) })
    }
}
