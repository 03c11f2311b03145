//! The JSON `hvs view`'s page reads and sends: the request bodies (strict: unknown fields
//! are refused) and the answers, built from the session's values with the CLI's own
//! formatting (`hvs locate --at`'s digits, `hvs info`'s and `hvs train`'s text).

use super::live::{Goal, HeadState};
use super::session::{DepthView, Retrained, Session};
use crate::vision::{Located, PairOutcome};
use serde::Deserialize;
use serde_json::{json, Value};

/// `POST /api/locate`: a left pixel of a pair.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocateRequest {
    /// The pair (0-based).
    pub pair: usize,
    /// Column (px, pixel-centre convention).
    pub u: f64,
    /// Row (px).
    pub v: f64,
}

/// `POST /api/look`: what the live head is to look at: `{"target": "pixel", "u": U, "v": V}`
/// (the object under this left pixel, then followed), `{"target": "nearest"}` or
/// `{"target": "home"}`.
#[derive(Debug, Deserialize)]
#[serde(tag = "target", rename_all = "lowercase", deny_unknown_fields)]
pub enum LookRequest {
    /// The object under a left pixel.
    Pixel {
        /// Column (px).
        u: f64,
        /// Row (px).
        v: f64,
    },
    /// The nearest object in the front region (a struct variant, so that an unknown field is
    /// refused: serde lets unit variants of a tagged enum through with any).
    Nearest {},
    /// Home, and hold.
    Home {},
}

impl LookRequest {
    /// The head's goal.
    pub fn goal(&self) -> Goal {
        match *self {
            LookRequest::Pixel { u, v } => Goal::Pixel([u, v]),
            LookRequest::Nearest {} => Goal::Nearest,
            LookRequest::Home {} => Goal::Home,
        }
    }
}

/// `POST /api/retrain`: which pairs to train on.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetrainRequest {
    /// One tick per pair of the capture set.
    #[serde(rename = "use")]
    pub ticked: Vec<bool>,
}

/// `GET /api/session`: the model panel, the pairs, and what the page can do.
pub fn session(s: &Session) -> Value {
    let b = &s.model.blob;
    let m = &b.meta;
    let matcher = b.matcher.map(|g| {
        json!({
            "fundamental": g.fundamental,
            "box_min_cm": g.out_min,
            "box_max_cm": g.out_max,
            "disparity_px": g.disparity,
            "right_scale": g.right_scale,
        })
    });
    let pairs: Vec<Value> = s
        .pairs
        .iter()
        .enumerate()
        .map(|(k, p)| json!({"index": k, "name": p.name, "z": p.z}))
        .collect();
    json!({
        "model": {
            "file": s.model_path.display().to_string(),
            "info": s.info,
            "topology": crate::data::model::shape(b),
            "family": b.family.name(),
            "train_points": m.train_points,
            "train_error_pct": m.train_error_pct,
            "matcher": matcher,
        },
        "live": s.frames.live(),
        "head": s.head.is_some(),
        "head_moves": s.head.as_ref().is_some_and(|h| h.moves()),
        "pairs": pairs,
        "locate_refused": s.locate_refused,
        "captures": s.captures.is_some(),
    })
}

/// `POST /api/locate`'s answer: the pixel asked for, and what `hvs locate --at` prints for
/// it, field by field and as its line.
pub fn located(pair: usize, l: &Located, ms: f64) -> Value {
    let t = l.texts();
    let field = |k: usize| t.as_ref().map(|t| t[k].clone());
    json!({
        "pair": pair,
        "u": l.left[0],
        "v": l.left[1],
        "status": l.status,
        "u_r": field(0),
        "v_r": field(1),
        "x": field(2),
        "y": field(3),
        "z": field(4),
        "score": field(5),
        "right": l.right,
        "line": l.line(),
        "ms": ms,
    })
}

/// `GET /api/head` (and `POST /api/look`'s answer): the live head after its latest frame,
/// the joints named as in `CAPTURES.csv`.
pub fn head(s: &HeadState) -> Value {
    let joints: serde_json::Map<String, Value> = crate::data::dataset::JOINT_COLUMNS
        .iter()
        .zip(s.joints.0)
        .map(|(k, v)| (k.to_string(), f32_json(v)))
        .collect();
    let goal = match s.goal {
        Goal::Idle => json!({"target": "idle"}),
        Goal::Pixel([u, v]) => json!({"target": "pixel", "u": u, "v": v}),
        Goal::Nearest => json!({"target": "nearest"}),
        Goal::Home => json!({"target": "home"}),
    };
    json!({
        "t_s": s.t_s,
        "frames": s.frames,
        "goal": goal,
        "status": s.status,
        "joints": joints,
        "moving": s.moving,
        "target_px": s.target_px,
        "xyz": s.xyz.map(|p| p.map(f32_json)),
        "err_px": s.err_px,
        "fps": s.fps,
        "right_scale": s.right_scale,
        "error": s.error,
    })
}

/// An `f32` as the JSON number of its shortest decimal (0.9, not 0.9000000357627869).
fn f32_json(v: f32) -> Value {
    v.to_string().parse::<f64>().map_or(Value::Null, |x| json!(x))
}

/// `GET /api/depth/{pair}`: what the depth map of a pair holds (its image is
/// `/api/depth/{pair}/image`).
pub fn depth(pair: usize, d: &DepthView) -> Value {
    json!({
        "pair": pair,
        "summary": d.depth.summary(),
        "returned": d.depth.returned(),
        "pixels": d.depth.xyz.len(),
        "z_box_cm": d.depth.z_box,
        "disparity_px": d.depth.d_range,
        "warnings": d.depth.warnings,
        "ms": d.ms,
    })
}

/// `GET /api/captures`: per pair what `hvs board detect` reports (corners, square size,
/// homography residuals, epipolar residuals) or why it was skipped.
pub fn captures(s: &Session) -> Option<Value> {
    let c = s.captures.as_ref()?;
    let det = &c.detection;
    let n = c.board.corner_count();
    let pairs: Vec<Value> = c
        .set
        .captures
        .iter()
        .zip(&det.outcomes)
        .enumerate()
        .map(|(k, (cap, o))| match o {
            PairOutcome::Found(p) => {
                let epi = det.epipolar[k]
                    .map(|[median, max]| json!({"median_px": median, "max_px": max}));
                json!({
                    "index": k,
                    "name": c.set.name(cap),
                    "z": cap.z,
                    "found": true,
                    "corners": n,
                    "square_px": p.left.square_px,
                    "homography_rms_px": [p.left.homography_rms, p.right.homography_rms],
                    "epipolar": epi,
                })
            }
            PairOutcome::Skipped(why) => json!({
                "index": k,
                "name": c.set.name(cap),
                "z": cap.z,
                "found": false,
                "skipped": why,
            }),
        })
        .collect();
    Some(json!({
        "board": format!("{}x{} inner corners", c.board.cols, c.board.rows),
        "sampson_rms_px": det.groups.iter().map(|g| g.rms_sampson).reduce(f64::max),
        "fundamental": det.fundamental_check(),
        "pairs": pairs,
    }))
}

/// `POST /api/retrain`'s answer.
pub fn retrained(r: &Retrained, ms: f64) -> Value {
    json!({
        "pairs": r.pairs,
        "points": r.points,
        "train_error_pct": r.train_error_pct,
        "summary": r.summary,
        "ms": ms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_located_point_has_the_numbers_of_its_line() {
        let l = Located {
            left: [300.0, 200.0],
            right: Some([273.985_883_685_464_2, 200.074_643_045_317_7]),
            xyz: Some([-13.298719, -16.096615, 115.02975]),
            score: 0.99912,
            status: "ok",
        };
        let v = located(0, &l, 1.0);
        assert_eq!(
            v["line"],
            "u_r=273.98587 v_r=200.07465 x=-13.298719 y=-16.096615 z=115.02975 cm (score 0.999)"
        );
        assert_eq!((v["u_r"].as_str(), v["z"].as_str()), (Some("273.98587"), Some("115.02975")));
        assert_eq!(v["score"], "0.999");
        let none = Located { right: None, xyz: None, status: "no_match", ..l };
        let v = located(0, &none, 1.0);
        assert_eq!(v["line"], "no trustworthy match: no_match");
        assert!(v["x"].is_null() && v["right"].is_null());
        // Requests are strict.
        assert!(serde_json::from_str::<LocateRequest>(r#"{"pair":0,"u":1,"v":2}"#).is_ok());
        for bad in
            [r#"{"pair":0,"u":1}"#, r#"{"pair":0,"u":1,"v":2,"x":0}"#, r#"{"pair":-1,"u":1,"v":2}"#]
        {
            assert!(serde_json::from_str::<LocateRequest>(bad).is_err(), "{bad}");
        }
        assert!(serde_json::from_str::<RetrainRequest>(r#"{"use":[true,false]}"#).is_ok());
        assert!(serde_json::from_str::<RetrainRequest>(r#"{"use":[1]}"#).is_err());
    }
}
