//! Scene files of the virtual head: the JSON of [`hvs_vision::scene`], with its `rig` read as
//! `hvs simulate` reads rigs (`{"case": N}` or a rig object, [`crate::data::rig`]).

use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::sim::camera::Rig;
use hvs_vision::scene::{Scene, SceneFile};
use std::path::Path;

/// A scene file, checked: the rig and the scene.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    /// The cameras' rig.
    pub rig: Rig,
    /// The objects and the wall.
    pub scene: Scene,
}

impl LoadedScene {
    /// The scene's virtual cameras on its rig, rendered as the loop renders
    /// ([`super::frames::loop_render_options`]; the noise seeded with `seed`, per frame):
    /// `hvs track --scene` and `hvs view --scene`.
    pub fn cameras(&self, seed: u64) -> super::frames::VirtualCameras {
        super::frames::VirtualCameras::new(
            hvs_shared::sim::posture::HeadRig::new(self.rig),
            self.scene.clone(),
            super::frames::loop_render_options(),
            seed,
        )
    }

    /// The cameras' image size (width, height).
    pub fn image_size(&self) -> (u32, u32) {
        (self.rig.width, self.rig.height)
    }
}

/// The rig of a scene file's `rig` value.
pub fn rig_of(v: &serde_json::Value) -> Result<Rig> {
    let obj =
        v.as_object().ok_or_else(|| anyhow!("rig: expected {{\"case\": N}} or a rig object"))?;
    if obj.contains_key("case") {
        if obj.len() != 1 {
            bail!("rig: {{\"case\": N}} takes no other field");
        }
        let n = obj["case"]
            .as_u64()
            .filter(|n| (1..=4).contains(n))
            .ok_or_else(|| anyhow!("rig.case: must be 1-4, got {}", obj["case"]))?;
        return hvs_shared::sim::presets::case(n as u8)
            .ok_or_else(|| anyhow!("rig.case: must be 1-4, got {n}"));
    }
    crate::data::rig::parse(&v.to_string(), None).map_err(|e| anyhow!("rig: {e:#}"))
}

/// Parses a scene file's text (errors name the field and its line).
pub fn parse(text: &str) -> Result<LoadedScene> {
    parse_lined(text).map_err(|(line, e)| match line {
        Some(n) => anyhow!("line {n}: {e:#}"),
        None => e,
    })
}

/// [`parse`], the refused field's line apart.
fn parse_lined(text: &str) -> Result<LoadedScene, (Option<usize>, anyhow::Error)> {
    let file = SceneFile::parse(text).map_err(|e| (None, anyhow!("{e}")))?;
    let rig = rig_of(&file.rig).map_err(|e| (hvs_vision::scene::field_line(text, "rig"), e))?;
    let scene = file.scene().map_err(|e| (e.line(text), anyhow!("{e}")))?;
    Ok(LoadedScene { rig, scene })
}

/// Reads a scene file; the error names the file and the line (`scene.json:7: objects[1]...`).
pub fn load(path: &Path) -> Result<LoadedScene> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    parse_lined(&text).map_err(|(line, e)| match line {
        Some(n) => anyhow!("{}:{n}: {e:#}", path.display()),
        None => anyhow!("{}: {e:#}", path.display()),
    })
}
