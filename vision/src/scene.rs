//! Scenes for the virtual head: textured spheres, boxes and boards in front of a textured wall,
//! moving in time, rendered through the head's cameras with per-pixel truth.
//!
//! # Scene file
//!
//! Strict JSON (unknown and duplicate fields refused, the field named in the error);
//! positions in the head frame of `hvs simulate` (cm, `X` right, `Y` down, `Z` forward):
//!
//! ```json
//! { "rig": {"case": 3}, "camera_fps": 30,
//!   "background": {"z_cm": 300, "texture_seed": 1},
//!   "objects": [ {"shape": "sphere", "radius_cm": 5, "centre_cm": [10, -5, 90],
//!                 "velocity_cm_s": [0, 0, 0], "texture_seed": 2} ] }
//! ```
//!
//! - `rig` is kept as JSON ([`SceneFile::rig`]): the rig parser lives in the host
//!   (`{"case": N}` or a rig object as `hvs simulate --rig` reads).
//! - `background`: a wall perpendicular to `Z` at `z_cm`, everywhere behind the objects.
//! - `objects[k]`: `shape` `sphere` (`radius_cm`), `box` (`size_cm`: `[sx, sy, sz]`, axis
//!   aligned), `plane` (a textured rectangle, `side_cm`: `[width, height]`, facing the head and
//!   slanted by `pitch_deg` about its horizontal axis, the top away from the head for a
//!   positive angle, then by `yaw_deg` about the vertical one, the right side away; each within
//!   +-85, default 0) or `board` (`board`: a `BOARD.json` object, upright, facing the head,
//!   with a white border one square wide); its position is either `centre_cm` (+ optional constant
//!   `velocity_cm_s`) or a `path` of timed waypoints `[{"t_s": 0, "centre_cm": [..]}, ..]`
//!   (linear between waypoints, held before the first and after the last); `texture_seed`
//!   (default 0) seeds its texture.
//!
//! # Textures
//!
//! Spheres, boxes, planes and the wall carry a seeded value-noise texture (two octaves, cells
//! of 2 cm and 0.8 cm on objects, 6 cm and 2.5 cm on the wall), a function of the surface point
//! relative to the object's centre (a plane's: of its two in-plane coordinates): fixed to the surface, high-frequency and non-repetitive
//! (good for stereo matching). Boards are chessboards (the colours of [`RenderOptions`]).
//!
//! # Rendering and truth
//!
//! [`render_scene`] casts the ray of every pixel centre ([`LensCamera::ray`]) into the scene at
//! time `t`; pixels whose object (or board colour) differs from a 4-neighbour's are
//! supersampled `n x n` ([`RenderOptions::supersample`]); then the blur, noise and 8-bit
//! rounding of [`crate::render`]. The truth ([`TruthImage`]) is the hit point of each pixel
//! centre's ray (head frame, so `Z` is the depth) and the object id ([`BACKGROUND`] for the
//! wall, `k + 1` for `objects[k]`, [`NONE`] for a ray that meets nothing).
//! [`SceneRender::true_match`] gives, for a left pixel, where the right camera sees the same
//! point, or `None` when it is occluded or out of the image.

use crate::board::Board;
use crate::invalid::{numbers, InvalidField, MAX_CM};
use crate::pfm::FloatImage;
use crate::render::{blur, class, quantise, Class, RayGrid, RenderError, RenderOptions};
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::sim::camera::{LensCamera, Vec3};
use hvs_shared::sim::posture::HeadRig;
use image::GrayImage;
use serde::Deserialize;
use std::fmt;

/// Object id of the background wall in [`TruthImage::object`].
pub const BACKGROUND: u16 = 0;
/// Object id of a ray that meets nothing.
pub const NONE: u16 = u16::MAX;
/// Most objects in a scene.
pub const MAX_OBJECTS: usize = 64;

/// The scene file as read (see the module documentation).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// The rig, as JSON: the host parses it.
    pub rig: serde_json::Value,
    /// Camera frame rate (frames per second, 1 to 1000).
    pub camera_fps: f64,
    /// The wall behind everything.
    pub background: Background,
    /// The objects, id `k + 1` for `objects[k]`.
    #[serde(default)]
    pub objects: Vec<ObjectSpec>,
}

/// The wall behind the objects.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Background {
    /// Depth of the wall (cm, > 0).
    pub z_cm: f64,
    /// Seed of its texture.
    #[serde(default)]
    pub texture_seed: u64,
}

/// Shapes of objects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShapeKind {
    /// A sphere (`radius_cm`).
    Sphere,
    /// An axis-aligned box (`size_cm`).
    Box,
    /// A slanted textured rectangle (`side_cm`, `pitch_deg`, `yaw_deg`).
    Plane,
    /// A chessboard (`board`).
    Board,
}

/// [`numbers`] for an optional field.
fn some_numbers<'de, D: serde::Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Option<[f64; N]>, D::Error> {
    numbers(d).map(Some)
}

/// One timed waypoint of a path.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    /// Time (s).
    pub t_s: f64,
    /// Centre at that time (cm).
    #[serde(deserialize_with = "numbers")]
    pub centre_cm: Vec3,
}

/// One object as written in the file (checked by [`SceneFile::scene`]).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// The shape.
    pub shape: ShapeKind,
    /// Sphere radius (cm).
    pub radius_cm: Option<f64>,
    /// Box sides (cm).
    #[serde(default, deserialize_with = "some_numbers")]
    pub size_cm: Option<Vec3>,
    /// Plane width and height (cm).
    #[serde(default, deserialize_with = "some_numbers")]
    pub side_cm: Option<[f64; 2]>,
    /// Plane slant about its horizontal axis (degrees, the top away from the head when
    /// positive).
    pub pitch_deg: Option<f64>,
    /// Plane slant about the vertical axis (degrees, the right side away when positive).
    pub yaw_deg: Option<f64>,
    /// Board description (a `BOARD.json` object).
    pub board: Option<crate::board::BoardSpec>,
    /// Centre at `t = 0` (cm).
    #[serde(default, deserialize_with = "some_numbers")]
    pub centre_cm: Option<Vec3>,
    /// Constant velocity (cm/s).
    #[serde(default, deserialize_with = "some_numbers")]
    pub velocity_cm_s: Option<Vec3>,
    /// Timed waypoints, instead of `centre_cm` and `velocity_cm_s`.
    pub path: Option<Vec<Waypoint>>,
    /// Texture seed.
    #[serde(default)]
    pub texture_seed: u64,
}

/// A checked shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Sphere of this radius (cm).
    Sphere {
        /// Radius (cm).
        radius_cm: f64,
    },
    /// Axis-aligned box of these sides (cm).
    Box {
        /// Sides (cm).
        size_cm: Vec3,
    },
    /// Textured rectangle of half sides `half_cm` along the unit in-plane axes `axes` (width,
    /// then height), whose cross product is `normal`.
    Plane {
        /// Half width and half height (cm).
        half_cm: [f64; 2],
        /// Unit axes of the width and the height (head frame).
        axes: [Vec3; 2],
        /// Unit normal.
        normal: Vec3,
    },
    /// Chessboard, upright, facing the head, with a white border one square wide.
    Board {
        /// The board.
        board: Board,
    },
}

/// How an object moves.
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// `centre + velocity t`.
    Linear {
        /// Centre at `t = 0` (cm).
        centre_cm: Vec3,
        /// Velocity (cm/s).
        velocity_cm_s: Vec3,
    },
    /// Linear between waypoints (times increasing), held outside them.
    Path(Vec<Waypoint>),
}

impl Motion {
    /// The centre at time `t` (s).
    pub fn centre_at(&self, t: f64) -> Vec3 {
        match self {
            Motion::Linear { centre_cm, velocity_cm_s } => {
                core::array::from_fn(|k| centre_cm[k] + velocity_cm_s[k] * t)
            }
            Motion::Path(w) => {
                let first = &w[0];
                if t <= first.t_s {
                    return first.centre_cm;
                }
                for p in w.windows(2) {
                    if t <= p[1].t_s {
                        let a = (t - p[0].t_s) / (p[1].t_s - p[0].t_s);
                        return core::array::from_fn(|k| {
                            p[0].centre_cm[k] + a * (p[1].centre_cm[k] - p[0].centre_cm[k])
                        });
                    }
                }
                w[w.len() - 1].centre_cm
            }
        }
    }
}

/// A checked object.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Its shape.
    pub shape: Shape,
    /// Its motion.
    pub motion: Motion,
    /// Its texture seed.
    pub texture_seed: u64,
}

/// A checked scene (without the rig).
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Camera frame rate (frames per second).
    pub camera_fps: f64,
    /// The wall.
    pub background: Background,
    /// The objects, id `k + 1` for `objects[k]`.
    pub objects: Vec<Object>,
}

/// Why a scene was refused: the field (a path such as `objects[1].radius_cm`, none for JSON
/// that does not parse) and the reason.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    /// The field, when a value was refused.
    pub field: Option<String>,
    /// Why.
    pub reason: String,
}

impl SceneError {
    /// The line (from 1) of the refused field's value in the scene file's `text`
    /// ([`field_line`]).
    pub fn line(&self, text: &str) -> Option<usize> {
        self.field.as_deref().and_then(|f| field_line(text, f))
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.field {
            Some(field) => write!(f, "{field}: {}", self.reason),
            None => f.write_str(&self.reason),
        }
    }
}

impl std::error::Error for SceneError {}

fn err(field: impl fmt::Display, reason: impl fmt::Display) -> SceneError {
    SceneError { field: Some(field.to_string()), reason: reason.to_string() }
}

/// The line (from 1) where the value of `field` (a path such as `objects[1].path[0].t_s`,
/// `size_cm[2]` or `background.z_cm`) starts in the JSON `text`; where part of the path is
/// missing (a field a shape needs), the line of the deepest value that is there. `None` when
/// the text is not JSON or the path's first step is not in it.
pub fn field_line(text: &str, field: &str) -> Option<usize> {
    use serde_json::value::RawValue;
    let mut steps: Vec<Result<&str, usize>> = Vec::new();
    for part in field.split('.') {
        let (name, rest) = part.split_once('[').map_or((part, ""), |(n, r)| (n, r));
        if !name.is_empty() {
            steps.push(Ok(name));
        }
        for index in rest.split('[') {
            if let Some(i) = index.strip_suffix(']').and_then(|i| i.parse().ok()) {
                steps.push(Err(i));
            }
        }
    }
    let mut value: &RawValue = serde_json::from_str(text).ok()?;
    let mut found = false;
    for step in steps {
        let next = match step {
            Ok(name) => {
                serde_json::from_str::<std::collections::BTreeMap<String, &RawValue>>(value.get())
                    .ok()
                    .and_then(|m| m.get(name).copied())
            }
            Err(i) => serde_json::from_str::<Vec<&RawValue>>(value.get())
                .ok()
                .and_then(|v| v.get(i).copied()),
        };
        match next {
            Some(v) => {
                value = v;
                found = true;
            }
            None => break,
        }
    }
    // The borrowed values are slices of `text`.
    let offset = (value.get().as_ptr() as usize).checked_sub(text.as_ptr() as usize)?;
    (found && offset <= text.len()).then(|| text[..offset].matches('\n').count() + 1)
}

fn check_vec(field: &str, v: &Vec3, bound: f64) -> Result<(), SceneError> {
    if v.iter().all(|x| x.is_finite() && x.abs() <= bound) {
        Ok(())
    } else {
        Err(err(field, format!("must be three finite numbers within +-{bound}, got {v:?}")))
    }
}

/// Largest slant of a plane (degrees): at 90 it would be seen edge on.
pub const MAX_SLANT_DEG: f64 = 85.0;

/// A plane's in-plane axes and normal: facing the head, pitched about `X` (the top away for a
/// positive angle), then yawed about `Y` (the right side away).
fn plane_frame(pitch_deg: f64, yaw_deg: f64) -> ([Vec3; 2], Vec3) {
    let (sp, cp) = (libm::sin(pitch_deg.to_radians()), libm::cos(pitch_deg.to_radians()));
    let (sy, cy) = (libm::sin(yaw_deg.to_radians()), libm::cos(yaw_deg.to_radians()));
    // Pitch: the height axis (Y down) turns to (0, cp, -sp), so the top (-Y) goes to +Z.
    // Yaw (x, y, z) -> (x cy - z sy, y, x sy + z cy): the width axis to (cy, 0, sy).
    let width = [cy, 0.0, sy];
    let height = [sp * sy, cp, -sp * cy];
    let normal = [
        width[1] * height[2] - width[2] * height[1],
        width[2] * height[0] - width[0] * height[2],
        width[0] * height[1] - width[1] * height[0],
    ];
    ([width, height], normal)
}

impl SceneFile {
    /// Reads a scene file's text strictly (unknown or duplicate fields, wrong types), the field
    /// of a wrong type named (`serde_path_to_error`); a leading byte-order mark is skipped.
    pub fn parse(text: &str) -> Result<SceneFile, SceneError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let invalid = |e: serde_json::Error| format!("invalid scene JSON: {e}");
        let mut de = serde_json::Deserializer::from_str(text);
        let file: SceneFile = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner();
            // A value of the wrong type has a field; text that is not JSON has none.
            let data = inner.classify() == serde_json::error::Category::Data;
            let field = (data && !path.is_empty() && path != ".").then_some(path);
            SceneError { field, reason: invalid(inner) }
        })?;
        de.end().map_err(|e| SceneError { field: None, reason: invalid(e) })?;
        Ok(file)
    }

    /// Checks every value (the field named, e.g. `objects[1].radius_cm`).
    pub fn scene(&self) -> Result<Scene, SceneError> {
        if !(self.camera_fps.is_finite() && (1.0..=1000.0).contains(&self.camera_fps)) {
            return Err(err(
                "camera_fps",
                format!("must be from 1 to 1000, got {}", self.camera_fps),
            ));
        }
        let b = self.background;
        if !(b.z_cm.is_finite() && b.z_cm > 0.0 && b.z_cm <= MAX_CM) {
            return Err(err(
                "background.z_cm",
                format!("must be > 0 and at most {MAX_CM}, got {}", shown(b.z_cm)),
            ));
        }
        if self.objects.len() > MAX_OBJECTS {
            return Err(err(
                "objects",
                format!("at most {MAX_OBJECTS} objects, got {}", self.objects.len()),
            ));
        }
        let objects = self
            .objects
            .iter()
            .enumerate()
            .map(|(k, o)| o.check(&format!("objects[{k}]")))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Scene { camera_fps: self.camera_fps, background: b, objects })
    }
}

/// A value as given, for a message: in exponent form when very large or small (`1e300`, not
/// 301 digits).
fn shown(x: f64) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e7).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

impl ObjectSpec {
    /// Refuses a plane's fields on another shape.
    fn no_plane_fields(
        &self,
        not_for: &dyn Fn(&str, bool) -> Result<(), SceneError>,
    ) -> Result<(), SceneError> {
        not_for("side_cm", self.side_cm.is_some())?;
        not_for("pitch_deg", self.pitch_deg.is_some())?;
        not_for("yaw_deg", self.yaw_deg.is_some())
    }

    fn check(&self, at: &str) -> Result<Object, SceneError> {
        let field = |f: &str| format!("{at}.{f}");
        let not_for = |f: &str, present: bool| {
            if present {
                Err(err(
                    field(f),
                    format!("not a field of a {:?} (remove it)", self.shape).to_lowercase(),
                ))
            } else {
                Ok(())
            }
        };
        let positive = |f: &str, x: f64| {
            if x.is_finite() && x > 0.0 && x <= MAX_CM {
                Ok(())
            } else {
                Err(err(field(f), format!("must be > 0 and at most {MAX_CM}, got {}", shown(x))))
            }
        };
        let shape = match self.shape {
            ShapeKind::Sphere => {
                not_for("size_cm", self.size_cm.is_some())?;
                not_for("board", self.board.is_some())?;
                self.no_plane_fields(&not_for)?;
                let r =
                    self.radius_cm.ok_or_else(|| err(field("radius_cm"), "a sphere needs it"))?;
                positive("radius_cm", r)?;
                Shape::Sphere { radius_cm: r }
            }
            ShapeKind::Box => {
                not_for("radius_cm", self.radius_cm.is_some())?;
                not_for("board", self.board.is_some())?;
                self.no_plane_fields(&not_for)?;
                let s = self.size_cm.ok_or_else(|| err(field("size_cm"), "a box needs it"))?;
                for (i, x) in s.iter().enumerate() {
                    positive(&format!("size_cm[{i}]"), *x)?;
                }
                Shape::Box { size_cm: s }
            }
            ShapeKind::Plane => {
                not_for("radius_cm", self.radius_cm.is_some())?;
                not_for("size_cm", self.size_cm.is_some())?;
                not_for("board", self.board.is_some())?;
                let s = self.side_cm.ok_or_else(|| err(field("side_cm"), "a plane needs it"))?;
                for (i, x) in s.iter().enumerate() {
                    positive(&format!("side_cm[{i}]"), *x)?;
                }
                let slant = |f: &str, a: Option<f64>| {
                    let a = a.unwrap_or(0.0);
                    if a.is_finite() && a.abs() <= MAX_SLANT_DEG {
                        Ok(a)
                    } else {
                        Err(err(
                            field(f),
                            format!("must be within +-{MAX_SLANT_DEG} degrees, got {a}"),
                        ))
                    }
                };
                let (axes, normal) = plane_frame(
                    slant("pitch_deg", self.pitch_deg)?,
                    slant("yaw_deg", self.yaw_deg)?,
                );
                Shape::Plane { half_cm: [0.5 * s[0], 0.5 * s[1]], axes, normal }
            }
            ShapeKind::Board => {
                not_for("radius_cm", self.radius_cm.is_some())?;
                not_for("size_cm", self.size_cm.is_some())?;
                self.no_plane_fields(&not_for)?;
                let b = self
                    .board
                    .as_ref()
                    .ok_or_else(|| err(field("board"), "a board needs a BOARD.json object"))?;
                let board = Board::from_spec(b).map_err(|e| err(field("board"), e))?;
                Shape::Board { board }
            }
        };
        let motion = match (&self.path, self.centre_cm) {
            (Some(_), Some(_)) => {
                return Err(err(
                    field("path"),
                    "give either centre_cm (+ velocity_cm_s) or a path, not both",
                ))
            }
            (None, None) => return Err(err(field("centre_cm"), "needed (or a path)")),
            (None, Some(c)) => {
                check_vec(&field("centre_cm"), &c, MAX_CM)?;
                let v = self.velocity_cm_s.unwrap_or([0.0; 3]);
                check_vec(&field("velocity_cm_s"), &v, MAX_CM)?;
                Motion::Linear { centre_cm: c, velocity_cm_s: v }
            }
            (Some(p), None) => {
                not_for("velocity_cm_s", self.velocity_cm_s.is_some())?;
                if p.is_empty() || p.len() > 10_000 {
                    return Err(err(
                        field("path"),
                        format!("needs 1 to 10000 waypoints, got {}", p.len()),
                    ));
                }
                for (i, w) in p.iter().enumerate() {
                    if !(w.t_s.is_finite() && w.t_s.abs() <= 1.0e7) {
                        return Err(err(
                            field(&format!("path[{i}].t_s")),
                            format!("must be finite, got {}", w.t_s),
                        ));
                    }
                    if i > 0 && w.t_s <= p[i - 1].t_s {
                        return Err(err(
                            field(&format!("path[{i}].t_s")),
                            format!("must be later than the waypoint before, got {}", w.t_s),
                        ));
                    }
                    check_vec(&field(&format!("path[{i}].centre_cm")), &w.centre_cm, MAX_CM)?;
                }
                Motion::Path(p.clone())
            }
        };
        Ok(Object { shape, motion, texture_seed: self.texture_seed })
    }
}

/// One object placed at one time: what a ray meets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// The shape.
    pub shape: Shape,
    /// Its centre (cm).
    pub centre: Vec3,
    /// Its texture seed.
    pub texture_seed: u64,
}

/// The scene frozen at one time `t`.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneAt {
    /// The time (s).
    pub t_s: f64,
    /// The wall.
    pub background: Background,
    /// The objects where they are at `t_s`, id `k + 1` for `objects[k]`.
    pub objects: Vec<Placed>,
}

impl Scene {
    /// The scene at time `t_s`.
    pub fn at(&self, t_s: f64) -> SceneAt {
        SceneAt {
            t_s,
            background: self.background,
            objects: self
                .objects
                .iter()
                .map(|o| Placed {
                    shape: o.shape,
                    centre: o.motion.centre_at(t_s),
                    texture_seed: o.texture_seed,
                })
                .collect(),
        }
    }
}

/// What a ray meets first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray (cm).
    pub t: f64,
    /// The point (head frame, cm).
    pub point: Vec3,
    /// The object id ([`BACKGROUND`] or `k + 1`).
    pub object: u16,
}

fn dot(a: &Vec3, b: &Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Half sides of a board's rectangle with its one-square border.
fn board_half(b: &Board) -> [f64; 2] {
    [(f64::from(b.cols) + 3.0) * 0.5 * b.square_cm, (f64::from(b.rows) + 3.0) * 0.5 * b.square_cm]
}

/// The nearest `t > 0` where the ray `o + t d` meets `p`.
fn intersect(p: &Placed, o: &Vec3, d: &Vec3) -> Option<f64> {
    let c = p.centre;
    match p.shape {
        Shape::Sphere { radius_cm } => {
            let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
            let b = dot(&oc, d);
            let q = dot(&oc, &oc) - radius_cm * radius_cm;
            let disc = b * b - q;
            if disc.is_nan() || disc < 0.0 {
                return None;
            }
            let s = libm::sqrt(disc);
            let t0 = -b - s;
            let t1 = -b + s;
            if t0 > 0.0 {
                Some(t0)
            } else if t1 > 0.0 {
                Some(t1)
            } else {
                None
            }
        }
        Shape::Box { size_cm } => {
            // A ray that misses the box's bounding sphere (its radius 1 % larger, far more than
            // any rounding) misses the box: `None` as the slabs below would say, without their
            // six divisions. A NaN goes on to the slabs.
            let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
            let hs = size_cm.map(|x| 0.5 * x);
            let r2 = dot(&hs, &hs) * 1.0201 + 1e-6;
            let b = dot(&oc, d);
            let disc = b * b - (dot(&oc, &oc) - r2);
            if disc < 0.0 {
                return None;
            }
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for k in 0..3 {
                let h = 0.5 * size_cm[k];
                let (a, b) = (c[k] - h - o[k], c[k] + h - o[k]);
                if d[k] == 0.0 {
                    if a > 0.0 || b < 0.0 {
                        return None;
                    }
                    continue;
                }
                let (t0, t1) = (a / d[k], b / d[k]);
                let (t0, t1) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
                lo = lo.max(t0);
                hi = hi.min(t1);
            }
            if lo > hi || hi <= 0.0 {
                None
            } else if lo > 0.0 {
                Some(lo)
            } else {
                Some(hi)
            }
        }
        Shape::Plane { half_cm, axes, normal } => {
            let den = dot(d, &normal);
            if den == 0.0 || den.is_nan() {
                return None;
            }
            let oc = [c[0] - o[0], c[1] - o[1], c[2] - o[2]];
            let t = dot(&oc, &normal) / den;
            if t.is_nan() || t <= 0.0 {
                return None;
            }
            let rel = [o[0] + t * d[0] - c[0], o[1] + t * d[1] - c[1], o[2] + t * d[2] - c[2]];
            (dot(&rel, &axes[0]).abs() < half_cm[0] && dot(&rel, &axes[1]).abs() < half_cm[1])
                .then_some(t)
        }
        Shape::Board { board } => {
            if d[2] == 0.0 {
                return None;
            }
            let t = (c[2] - o[2]) / d[2];
            if t.is_nan() || t <= 0.0 {
                return None;
            }
            let [hx, hy] = board_half(&board);
            let x = o[0] + t * d[0] - c[0];
            let y = o[1] + t * d[1] - c[1];
            (x.abs() < hx && y.abs() < hy).then_some(t)
        }
    }
}

impl SceneAt {
    /// What the ray from `o` along the unit direction `d` meets first.
    pub fn cast(&self, o: &Vec3, d: &Vec3) -> Option<Hit> {
        let mut best: Option<(f64, u16)> = None;
        if d[2] != 0.0 {
            let t = (self.background.z_cm - o[2]) / d[2];
            if t > 0.0 && t.is_finite() {
                best = Some((t, BACKGROUND));
            }
        }
        for (k, p) in self.objects.iter().enumerate() {
            if let Some(t) = intersect(p, o, d) {
                if best.is_none_or(|(b, _)| t < b) {
                    best = Some((t, k as u16 + 1));
                }
            }
        }
        let (t, object) = best?;
        let point = core::array::from_fn(|k| o[k] + t * d[k]);
        point.iter().all(|x: &f64| x.is_finite()).then_some(Hit { t, point, object })
    }

    /// The grey level and colour class of a hit (the class tells edges for anti-aliasing).
    fn shade(&self, hit: &Hit, opt: &RenderOptions, cells: &mut [Cell; 2]) -> (f32, u8) {
        if hit.object == BACKGROUND {
            let p = hit.point;
            let g = texture_cached(
                [p[0], p[1], 0.0],
                self.background.texture_seed,
                [1.0 / 6.0, 1.0 / 2.5],
                cells,
            );
            return (g, 0);
        }
        let o = &self.objects[usize::from(hit.object - 1)];
        let c = o.centre;
        let rel = [hit.point[0] - c[0], hit.point[1] - c[1], hit.point[2] - c[2]];
        match o.shape {
            Shape::Board { board } => {
                let k = class(&board, board.square_cm, rel[0], rel[1]);
                let level = match k {
                    Class::Black => opt.black,
                    Class::White | Class::Background => opt.white,
                };
                (f32::from(level), if k == Class::Black { 1 } else { 2 })
            }
            Shape::Plane { axes, .. } => {
                // The in-plane coordinates, at a whole third coordinate: a 2-D texture as the
                // wall's, fixed to the surface whatever the slant.
                let p = [dot(&rel, &axes[0]), dot(&rel, &axes[1]), 0.0];
                (texture_cached(p, o.texture_seed, [1.0 / 2.0, 1.0 / 0.8], cells), 0)
            }
            _ => (texture_cached(rel, o.texture_seed, [1.0 / 2.0, 1.0 / 0.8], cells), 0),
        }
    }
}

/// 64-bit mix (splitmix64's finaliser).
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A value in `[0, 1)` for lattice point `(x, y, z)` of `seed`.
#[inline(always)]
fn lattice(x: i64, y: i64, z: i64, seed: u64) -> f64 {
    let h = mix(seed
        ^ (x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f)
        ^ (z as u64).wrapping_mul(0x1656_67b1_9e37_79f9));
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The lattice values of the last cell [`value_noise_cached`] used: consecutive samples of a
/// row mostly fall in the same cell, whose 4 or 8 hashes are then not recomputed (the lattice
/// is a pure function, so the values, and every bit of the noise, are the same).
#[derive(Clone, Copy)]
struct Cell {
    key: (i64, i64, i64, u64),
    /// The corners `(ix + i, iy + j, iz)` at `[j * 2 + i]`, then those of `iz + 1`.
    value: [f64; 8],
    /// Whether the corners of `iz + 1` are filled.
    upper: bool,
    /// Whether `key` is valid.
    valid: bool,
}

impl Cell {
    const EMPTY: Cell = Cell { key: (0, 0, 0, 0), value: [0.0; 8], upper: false, valid: false };
}

/// `x.floor()` without the call to the library's `floor` (no SSE4.1 in the default target):
/// for `|x| < 2^52` the truncation is exact and one below it for a negative fraction. Only the
/// sign of a zero may differ (`-0.0` gives `0.0`), which changes neither the cell `fx as i64`
/// nor the fraction's `smooth(x - fx)` (both zeros give `+0.0`).
#[inline(always)]
fn floor(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64 as f64;
        if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x.floor()
    }
}

/// Value noise at `p` (cells of size 1): smooth trilinear interpolation of lattice values,
/// with the lattice values of the last cell kept in `cell`.
#[inline(always)]
fn value_noise_cached(p: Vec3, seed: u64, cell: &mut Cell) -> f64 {
    let (fx, fy, fz) = (floor(p[0]), floor(p[1]), floor(p[2]));
    let (ix, iy, iz) = (fx as i64, fy as i64, fz as i64);
    let smooth = |x: f64| x * x * (3.0 - 2.0 * x);
    let (sx, sy, sz) = (smooth(p[0] - fx), smooth(p[1] - fy), smooth(p[2] - fz));
    let lerp = |a: f64, b: f64, t: f64| a + t * (b - a);
    let key = (ix, iy, iz, seed);
    if !cell.valid || cell.key != key {
        cell.key = key;
        cell.valid = true;
        cell.upper = false;
        cell.value[0] = lattice(ix, iy, iz, seed);
        cell.value[1] = lattice(ix + 1, iy, iz, seed);
        cell.value[2] = lattice(ix, iy + 1, iz, seed);
        cell.value[3] = lattice(ix + 1, iy + 1, iz, seed);
    }
    let v = &cell.value;
    let lower = {
        let a = lerp(v[0], v[1], sx);
        let b = lerp(v[2], v[3], sx);
        lerp(a, b, sy)
    };
    if sz == 0.0 {
        // A surface at a whole z (the wall): the four corners of one plane.
        return lower;
    }
    if !cell.upper {
        cell.upper = true;
        cell.value[4] = lattice(ix, iy, iz + 1, seed);
        cell.value[5] = lattice(ix + 1, iy, iz + 1, seed);
        cell.value[6] = lattice(ix, iy + 1, iz + 1, seed);
        cell.value[7] = lattice(ix + 1, iy + 1, iz + 1, seed);
    }
    let v = &cell.value;
    let upper = {
        let a = lerp(v[4], v[5], sx);
        let b = lerp(v[6], v[7], sx);
        lerp(a, b, sy)
    };
    lerp(lower, upper, sz)
}

/// The grey level of a textured surface at `p` (relative to the object): two octaves of
/// value noise of frequencies `freq` (1/cm), contrast stretched to about 25..235.
#[cfg(test)]
fn texture(p: Vec3, seed: u64, freq: [f64; 2]) -> f32 {
    texture_cached(p, seed, freq, &mut [Cell::EMPTY; 2])
}

/// [`texture`] with the last cell of each octave kept in `cells`.
#[inline(always)]
fn texture_cached(p: Vec3, seed: u64, freq: [f64; 2], cells: &mut [Cell; 2]) -> f32 {
    let a = value_noise_cached(p.map(|x| x * freq[0]), seed, &mut cells[0]);
    let b = value_noise_cached(p.map(|x| x * freq[1]), mix(seed.wrapping_add(1)), &mut cells[1]);
    let x = 0.6 * a + 0.4 * b; // mean 0.5, mostly 0.2..0.8
    ((x - 0.5) * 2.2 * 150.0 + 130.0).clamp(10.0, 245.0) as f32
}

/// Per-pixel truth of one image: the hit point of each pixel centre's ray and its object.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthImage {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Hit point (head frame, cm; `Z` is the depth), row-major; NaN where [`NONE`].
    pub point: Vec<[f32; 3]>,
    /// Object id, row-major ([`BACKGROUND`], `k + 1` for `objects[k]`, [`NONE`]).
    pub object: Vec<u16>,
}

impl TruthImage {
    /// The depth `Z` (cm) of pixel `(c, r)`, `None` out of the image or where nothing is hit.
    pub fn z(&self, c: u32, r: u32) -> Option<f32> {
        self.hit(c, r).map(|(p, _)| p[2])
    }

    /// The hit point and object of pixel `(c, r)`.
    pub fn hit(&self, c: u32, r: u32) -> Option<([f32; 3], u16)> {
        if c >= self.width || r >= self.height {
            return None;
        }
        let k = (r * self.width + c) as usize;
        (self.object[k] != NONE).then(|| (self.point[k], self.object[k]))
    }
}

/// A rendered pair with its truth, and what is needed to ask it questions.
#[derive(Debug, Clone)]
pub struct SceneRender {
    /// Left image.
    pub left: GrayImage,
    /// Right image.
    pub right: GrayImage,
    /// Truth of the left image.
    pub truth_left: TruthImage,
    /// Truth of the right image.
    pub truth_right: TruthImage,
    /// The two cameras at the posture rendered (left, right).
    pub cameras: [LensCamera; 2],
    /// The scene at the time rendered.
    pub scene: SceneAt,
}

/// Relative distance within which two hits are the same point (visibility test).
const SAME_POINT_REL: f64 = 1.0e-6;

impl SceneRender {
    /// Where the right camera sees the point the centre of left pixel `(c, r)` sees:
    /// unrounded `(u_r, v_r)` (pixel-centre convention of [`crate::render`]), `None` if the left
    /// pixel sees nothing, the point projects outside the right image, or something stands
    /// between it and the right camera.
    pub fn true_match(&self, c: u32, r: u32) -> Option<[f64; 2]> {
        let k = (r as usize) * (self.truth_left.width as usize) + c as usize;
        if c >= self.truth_left.width || r >= self.truth_left.height {
            return None;
        }
        if self.truth_left.object[k] == NONE {
            return None;
        }
        // Re-cast the left ray in f64 (the stored point is f32).
        let (o, d) = self.cameras[0].ray(f64::from(c), f64::from(r))?;
        let hit = self.scene.cast(&o, &d)?;
        self.visible_in(1, &hit.point)
    }

    /// The objects (indices into the scene's `objects`) that no pixel of either image sees:
    /// behind the head, out of both views, or hidden behind other objects.
    pub fn unseen_objects(&self) -> Vec<usize> {
        let mut seen = vec![false; self.scene.objects.len()];
        for id in self.truth_left.object.iter().chain(&self.truth_right.object) {
            if let Some(s) = (*id as usize).checked_sub(1).and_then(|k| seen.get_mut(k)) {
                *s = true;
            }
        }
        seen.iter().enumerate().filter(|(_, s)| !**s).map(|(k, _)| k).collect()
    }

    /// The truth in the formats `hvs depth` writes its answers in, rows first: the left
    /// image's depth (one channel, `Z` in cm of the point each pixel centre sees, `+inf` where
    /// its ray meets nothing) and its true matches (three channels, `u_r, v_r, 1` where the
    /// right camera sees that point, [`SceneRender::true_match`]; `+inf, +inf, 0` where not).
    pub fn truth_images(&self) -> (FloatImage, FloatImage) {
        use rayon::prelude::*;
        let (w, h) = (self.truth_left.width, self.truth_left.height);
        let rows: Vec<(Vec<f32>, Vec<f32>)> = (0..h)
            .into_par_iter()
            .map(|r| {
                let mut z = Vec::with_capacity(w as usize);
                let mut m = Vec::with_capacity(3 * w as usize);
                for c in 0..w {
                    z.push(self.truth_left.z(c, r).unwrap_or(f32::INFINITY));
                    m.extend(match self.true_match(c, r) {
                        Some([u, v]) => [u as f32, v as f32, 1.0],
                        None => [f32::INFINITY, f32::INFINITY, 0.0],
                    });
                }
                (z, m)
            })
            .collect();
        let (z, m): (Vec<Vec<f32>>, Vec<Vec<f32>>) = rows.into_iter().unzip();
        let image = |channels, data: Vec<Vec<f32>>| FloatImage {
            width: w,
            height: h,
            channels,
            data: data.concat(),
        };
        (image(1, z), image(3, m))
    }

    /// The pixel where camera `cam` (0 left, 1 right) sees head-frame point `p`, `None` when
    /// outside the image or occluded.
    pub fn visible_in(&self, cam: usize, p: &Vec3) -> Option<[f64; 2]> {
        let camera = &self.cameras[cam];
        let px = camera.project(p)?;
        let (w, h) = (f64::from(self.left.width()), f64::from(self.left.height()));
        if !(px[0] >= -0.5 && px[0] < w - 0.5 && px[1] >= -0.5 && px[1] < h - 0.5) {
            return None;
        }
        let o = camera.camera.center;
        let v = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
        let n = libm::sqrt(dot(&v, &v));
        if n.is_nan() || n <= 0.0 {
            return None;
        }
        let d = v.map(|x| x / n);
        let hit = self.scene.cast(&o, &d)?;
        (hit.t >= n * (1.0 - SAME_POINT_REL) - 1e-6).then_some(px)
    }
}

/// Renders the pair of `scene` (at one time) through `head` at `joints`. Sensor noise comes
/// from a ChaCha8 stream seeded with `seed` (left image first): the same arguments give the
/// same bytes. `opt.margin_cm` is not used (a board's border is one square).
pub fn render_scene(
    head: &HeadRig,
    joints: &Joints,
    scene: &SceneAt,
    opt: &RenderOptions,
    seed: u64,
) -> Result<SceneRender, RenderError> {
    use rand::SeedableRng;
    opt.validate()?;
    let (w, h) = (head.rig.width, head.rig.height);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > crate::image_file::MAX_PIXELS {
        return Err(InvalidField::new(
            "rig.width/height",
            format!(
                "the image must have from 1 to {} pixels, got {w}x{h}",
                crate::image_file::MAX_PIXELS
            ),
        )
        .into());
    }
    if !head.distortion.iter().all(|d| d.is_finite()) {
        return Err(InvalidField::new("distortion", "k1 and k2 must be finite").into());
    }
    if !joints.0.iter().all(|j| j.is_finite()) {
        return Err(InvalidField::new("joints", format!("must be finite, got {joints:?}")).into());
    }
    let cameras = head.cameras(joints);
    let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(seed);
    let mut out = cameras.iter().map(|cam| {
        let (mut buf, truth) = shade_camera(cam, scene, opt, w, h);
        if opt.blur_sigma_px > 0.0 {
            blur(&mut buf, w as usize, h as usize, opt.blur_sigma_px);
        }
        (quantise(&buf, w, h, opt.noise_sigma, &mut rng), truth)
    });
    let (left, truth_left) = out.next().expect("two cameras");
    let (right, truth_right) = out.next().expect("two cameras");
    Ok(SceneRender { left, right, truth_left, truth_right, cameras, scene: scene.clone() })
}

/// Grey levels (row-major `f32`) and truth of one camera.
fn shade_camera(
    cam: &LensCamera,
    scene: &SceneAt,
    opt: &RenderOptions,
    w: u32,
    h: u32,
) -> (Vec<f32>, TruthImage) {
    use rayon::prelude::*;
    let (wu, hu) = (w as usize, h as usize);
    let n = wu * hu;
    let sample_ray = |o: &Vec3, d: &Vec3, cells: &mut [Cell; 2]| -> Option<(Hit, f32, u8)> {
        let hit = scene.cast(o, d)?;
        let (g, k) = scene.shade(&hit, opt, cells);
        Some((hit, g, k))
    };
    let sample = |u: f64, v: f64, cells: &mut [Cell; 2]| -> Option<(Hit, f32, u8)> {
        let (o, d) = cam.ray(u, v)?;
        let hit = scene.cast(&o, &d)?;
        let (g, k) = scene.shade(&hit, opt, cells);
        Some((hit, g, k))
    };
    let background = f32::from(opt.background);
    let grid = RayGrid::new(cam, wu, hu, 0.0, 0.0);
    // One sample per pixel, rows in parallel (each pixel's value depends on nothing else,
    // so the image is the same on any number of threads).
    let rows: Vec<_> = (0..hu)
        .into_par_iter()
        .map(|r| {
            let mut row = Vec::with_capacity(wu);
            let mut cells = [Cell::EMPTY; 2];
            for c in 0..wu {
                let s = match &grid {
                    Some(g) => {
                        let (o, d) = g.ray(c, r);
                        sample_ray(&o, &d, &mut cells)
                    }
                    None => sample(c as f64, r as f64, &mut cells),
                };
                row.push(match s {
                    Some((hit, g, k)) => {
                        (g, (hit.object, k), hit.point.map(|x| x as f32), hit.object)
                    }
                    None => (background, (NONE, 0), [f32::NAN; 3], NONE),
                });
            }
            row
        })
        .collect();
    let mut grey = Vec::with_capacity(n);
    let mut key = Vec::with_capacity(n);
    let mut point = Vec::with_capacity(n);
    let mut object = Vec::with_capacity(n);
    for (g, k, p, o) in rows.into_iter().flatten() {
        grey.push(g);
        key.push(k);
        point.push(p);
        object.push(o);
    }
    // Supersample pixels on an edge (object or board colour differs from a 4-neighbour),
    // rows in parallel.
    let ns = opt.supersample as usize;
    if ns > 1 {
        grey.par_chunks_mut(wu).enumerate().for_each(|(r, row)| {
            let mut cells = [Cell::EMPTY; 2];
            for (c, g) in row.iter_mut().enumerate() {
                let i = r * wu + c;
                let k = key[i];
                let edge = (c > 0 && key[i - 1] != k)
                    || (c + 1 < wu && key[i + 1] != k)
                    || (r > 0 && key[i - wu] != k)
                    || (r + 1 < hu && key[i + wu] != k);
                if !edge {
                    continue;
                }
                *g = crate::render::supersample(c, r, ns, |u, v| {
                    sample(u, v, &mut cells).map_or(background, |s| s.1)
                });
            }
        });
    }
    (grey, TruthImage { width: w, height: h, point, object })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_is_fixed_and_varied() {
        let a = texture([1.0, 2.0, 3.0], 5, [1.0, 2.0]);
        assert_eq!(a, texture([1.0, 2.0, 3.0], 5, [1.0, 2.0]));
        let vals: Vec<f32> =
            (0..200).map(|i| texture([i as f64 * 0.37, 0.0, 0.0], 5, [1.0, 2.0])).collect();
        let mean = vals.iter().sum::<f32>() / 200.0;
        let sd = (vals.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / 200.0).sqrt();
        assert!(sd > 25.0, "texture contrast {sd}");
        assert_ne!(a, texture([1.0, 2.0, 3.0], 6, [1.0, 2.0]));
    }

    #[test]
    fn path_interpolates_and_holds() {
        let m = Motion::Path(vec![
            Waypoint { t_s: 0.0, centre_cm: [0.0, 0.0, 100.0] },
            Waypoint { t_s: 2.0, centre_cm: [20.0, 0.0, 100.0] },
        ]);
        assert_eq!(m.centre_at(-1.0), [0.0, 0.0, 100.0]);
        assert_eq!(m.centre_at(1.0), [10.0, 0.0, 100.0]);
        assert_eq!(m.centre_at(5.0), [20.0, 0.0, 100.0]);
    }

    #[test]
    fn box_and_sphere_intersections() {
        let s = Placed {
            shape: Shape::Sphere { radius_cm: 5.0 },
            centre: [0.0, 0.0, 100.0],
            texture_seed: 0,
        };
        let t = intersect(&s, &[0.0; 3], &[0.0, 0.0, 1.0]).unwrap();
        assert!((t - 95.0).abs() < 1e-12);
        let b = Placed {
            shape: Shape::Box { size_cm: [10.0, 10.0, 10.0] },
            centre: [0.0, 0.0, 100.0],
            texture_seed: 0,
        };
        let t = intersect(&b, &[0.0; 3], &[0.0, 0.0, 1.0]).unwrap();
        assert!((t - 95.0).abs() < 1e-12);
        assert!(intersect(&b, &[20.0, 0.0, 0.0], &[0.0, 0.0, 1.0]).is_none());
    }

    #[test]
    fn plane_slants_and_intersections() {
        for (pitch, yaw) in [(0.0, 0.0), (30.0, 0.0), (0.0, -40.0), (60.0, 25.0), (-85.0, 85.0)] {
            let ([a, b], n) = plane_frame(pitch, yaw);
            for (u, v, want) in [(&a, &a, 1.0), (&b, &b, 1.0), (&n, &n, 1.0), (&a, &b, 0.0)] {
                assert!((dot(u, v) - want).abs() < 1e-12, "{pitch} {yaw}");
            }
            assert!((dot(&a, &n)).abs() < 1e-12 && (dot(&b, &n)).abs() < 1e-12);
        }
        // The top (-height axis) goes away for a positive pitch, the right side for a
        // positive yaw.
        assert!(plane_frame(30.0, 0.0).0[1][2] < 0.0);
        assert!(plane_frame(0.0, 30.0).0[0][2] > 0.0);
        let (axes, normal) = plane_frame(50.0, -20.0);
        let p = Placed {
            shape: Shape::Plane { half_cm: [20.0, 10.0], axes, normal },
            centre: [5.0, -3.0, 120.0],
            texture_seed: 0,
        };
        // A ray through the centre meets it there; a hit lies on the plane, inside it.
        let d = {
            let l = libm::sqrt(dot(&p.centre, &p.centre));
            p.centre.map(|x| x / l)
        };
        let t = intersect(&p, &[0.0; 3], &d).unwrap();
        assert!((t - libm::sqrt(dot(&p.centre, &p.centre))).abs() < 1e-9);
        let d2 = {
            let q = [10.0, 1.0, 100.0];
            let l = libm::sqrt(dot(&q, &q));
            q.map(|x| x / l)
        };
        let t = intersect(&p, &[0.0; 3], &d2).unwrap();
        let rel: Vec3 = core::array::from_fn(|k| t * d2[k] - p.centre[k]);
        assert!(dot(&rel, &normal).abs() < 1e-9);
        assert!(dot(&rel, &axes[0]).abs() < 20.0 && dot(&rel, &axes[1]).abs() < 10.0);
        // Beside it, and behind the eye: nothing.
        assert!(intersect(&p, &[0.0; 3], &[1.0, 0.0, 0.0]).is_none());
        assert!(intersect(&p, &[0.0, 0.0, 200.0], &[0.0, 0.0, 1.0]).is_none());
    }

    #[test]
    fn a_boards_errors_give_their_place_in_the_scene_file() {
        // A scene with one board object, the board on line 3.
        let read = |board: &str| {
            let text = format!(
                "{{\"rig\": {{\"case\": 3}}, \"camera_fps\": 30,\n \"background\": {{\"z_cm\": 300}},\n \"objects\": [{{\"shape\": \"board\", \"centre_cm\": [0, 0, 100], \"board\": {board}}}]}}"
            );
            SceneFile::parse(&text).and_then(|f| f.scene()).map(|_| ())
        };
        let scene = |board: &str| read(board).unwrap_err().to_string();
        let ok = r#"{"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6}"#;
        assert!(read(ok).is_ok());
        let e = scene(
            r#"{"pattern": "chessboard", "inner_corners": [9, 6], "square_cm": 6, "colour": 1}"#,
        );
        assert!(e.contains("unknown field `colour`") && e.contains("at line 3"), "{e}");
        let e = scene(r#"{"pattern": "chessboard", "inner_corners": [9, 6, 1], "square_cm": 6}"#);
        assert!(e.contains("expected 2 numbers in brackets, got 3 at line 3"), "{e}");
        let e = scene(r#"{"pattern": "chessboard", "inner_corners": [1, 6], "square_cm": 6}"#);
        assert!(e.contains("objects[0].board") && e.contains("cols"), "{e}");
    }

    #[test]
    fn a_value_of_the_wrong_type_is_named_and_a_byte_order_mark_is_skipped() {
        let text = |radius: &str, seed: &str| {
            format!(
                "{{\"rig\": {{\"case\": 3}}, \"camera_fps\": 30,\n \"background\": {{\"z_cm\": 300}},\n \"objects\": [{{\"shape\": \"sphere\", \"radius_cm\": {radius}, \"centre_cm\": [0, 0, 100], \"texture_seed\": {seed}}}]}}"
            )
        };
        let e = SceneFile::parse(&text("\"5\"", "2")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("objects[0].radius_cm"), "{e}");
        assert!(
            e.to_string().contains("invalid type: string \"5\", expected f64 at line 3"),
            "{e}"
        );
        let e = SceneFile::parse(&text("5", "-1")).unwrap_err();
        assert_eq!(e.field.as_deref(), Some("objects[0].texture_seed"), "{e}");
        let e = SceneFile::parse(&text("1e300", "2")).unwrap().scene().unwrap_err().to_string();
        assert!(e.contains("must be > 0 and at most 100000, got 1e300"), "{e}");
        let with_bom = format!("\u{feff}{}", text("5", "2"));
        assert!(SceneFile::parse(&with_bom).unwrap().scene().is_ok());
        // Text after the scene is refused, as before.
        assert!(SceneFile::parse(&format!("{} x", text("5", "2"))).is_err());
    }

    #[test]
    fn plane_fields_are_checked() {
        let scene = |o: &str| {
            SceneFile::parse(&format!(
                r#"{{"rig": {{"case": 3}}, "camera_fps": 30, "background": {{"z_cm": 300}}, "objects": [{o}]}}"#
            ))
            .unwrap()
            .scene()
        };
        // A list of the wrong length says how many numbers it wanted.
        for (o, want) in [
            (
                r#"{"shape": "plane", "side_cm": [4, 4, 4], "centre_cm": [0, 0, 100]}"#,
                "expected 2 numbers in brackets, got 3",
            ),
            (
                r#"{"shape": "box", "size_cm": [4, 4], "centre_cm": [0, 0, 100]}"#,
                "expected 3 numbers in brackets, got 2",
            ),
            (
                r#"{"shape": "sphere", "radius_cm": 3, "centre_cm": [0, 100]}"#,
                "expected 3 numbers in brackets, got 2",
            ),
            (
                r#"{"shape": "sphere", "radius_cm": 3, "path": [{"t_s": 0, "centre_cm": [0, 0, 1, 100]}]}"#,
                "expected 3 numbers in brackets, got 4",
            ),
        ] {
            let text = format!(
                r#"{{"rig": {{"case": 3}}, "camera_fps": 30, "background": {{"z_cm": 300}}, "objects": [{o}]}}"#
            );
            let e = SceneFile::parse(&text).unwrap_err().to_string();
            assert!(e.contains(want), "{o}: {e}");
        }
        let ok = scene(
            r#"{"shape": "plane", "side_cm": [40, 30], "pitch_deg": 60, "centre_cm": [0, 0, 100]}"#,
        );
        assert!(matches!(ok.unwrap().objects[0].shape, Shape::Plane { half_cm: [20.0, 15.0], .. }));
        for (o, want) in [
            (
                r#"{"shape": "plane", "centre_cm": [0, 0, 100]}"#,
                "objects[0].side_cm: a plane needs it",
            ),
            (
                r#"{"shape": "plane", "side_cm": [40, 0], "centre_cm": [0, 0, 100]}"#,
                "objects[0].side_cm[1]: must be > 0",
            ),
            (
                r#"{"shape": "plane", "side_cm": [4, 4], "yaw_deg": 90, "centre_cm": [0, 0, 100]}"#,
                "objects[0].yaw_deg: must be within +-85",
            ),
            (
                r#"{"shape": "plane", "side_cm": [4, 4], "radius_cm": 3, "centre_cm": [0, 0, 100]}"#,
                "objects[0].radius_cm: not a field of a plane",
            ),
            (
                r#"{"shape": "sphere", "radius_cm": 3, "pitch_deg": 10, "centre_cm": [0, 0, 100]}"#,
                "objects[0].pitch_deg: not a field of a sphere",
            ),
            (
                r#"{"shape": "box", "size_cm": [3, 3, 3], "side_cm": [3, 3], "centre_cm": [0, 0, 100]}"#,
                "objects[0].side_cm: not a field of a box",
            ),
        ] {
            let e = scene(o).unwrap_err().to_string();
            assert!(e.starts_with(want), "{o}: {e}");
        }
    }
}
