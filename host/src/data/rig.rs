//! Camera rigs from JSON files, in the form of the case entries of `cases.json`.
//!
//! Two shapes are accepted:
//!
//! 1. One rig, a flat object:
//!    `{"phi_u_left": 285.8, "phi_u_right": 228.7, "alpha_left": -0.0455, "alpha_right": 0.0455,
//!    "beta0": 0.0087, "phi0": 0.0087}` with optional `phi_v_left`, `phi_v_right` (default: the
//!    `phi_u` of the same camera), `u0`, `v0`, `width`, `height` (default 320, 240, 640, 480)
//!    and `half_baseline_cm` (default 5.25). `label`, `phi_v_equals_phi_u` and
//!    `traditional_test_error_range_pct` are accepted and ignored.
//! 2. A `cases.json`-like file: `{"cases": {"1": {...}, ...}, "image": {...},
//!    "half_baseline_cm": ...}`; the top-level `image` and `half_baseline_cm` are the defaults
//!    of every case, and a case is chosen by number (or is the only one).
//!
//! Angles are radians, lengths cm, `Phi` pixels. Unknown fields are errors (a misspelt
//! optional field would otherwise be silently replaced by its default).

use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::gaze::HALF_BASELINE_CM;
use hvs_shared::sim::camera::Rig;
use serde_json::{Map, Value};
use std::path::Path;

const REQUIRED: [&str; 6] =
    ["phi_u_left", "phi_u_right", "alpha_left", "alpha_right", "beta0", "phi0"];
const OPTIONAL: [&str; 7] =
    ["phi_v_left", "phi_v_right", "u0", "v0", "width", "height", "half_baseline_cm"];
const IGNORED: [&str; 3] = ["label", "phi_v_equals_phi_u", "traditional_test_error_range_pct"];

/// Reads a rig from `path`; `case` picks an entry of a `cases.json`-like file.
pub fn load(path: &Path, case: Option<u8>) -> Result<Rig> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    parse(&text, case).map_err(|e| anyhow!("{}: {e:#}", path.display()))
}

/// Parses a rig from JSON text (see the module documentation for the accepted shapes).
pub fn parse(text: &str, case: Option<u8>) -> Result<Rig> {
    // serde_json keeps the last of duplicated keys silently; a rig file with `"u0"` twice
    // is refused instead, naming the key.
    let mut de = serde_json::Deserializer::from_str(text);
    serde::de::DeserializeSeed::deserialize(Unique(String::new()), &mut de)
        .and_then(|()| de.end())
        .map_err(|e| anyhow!("invalid JSON: {e}"))?;
    let v: Value = serde_json::from_str(text).map_err(|e| anyhow!("invalid JSON: {e}"))?;
    let obj = v.as_object().ok_or_else(|| anyhow!("expected a JSON object"))?;
    match obj.get("cases") {
        Some(cases) => {
            let cases = cases
                .as_object()
                .ok_or_else(|| anyhow!("\"cases\": expected an object of numbered cases"))?;
            let key = match case {
                Some(n) => n.to_string(),
                None if cases.len() == 1 => cases.keys().next().cloned().unwrap_or_default(),
                None => bail!(
                    "the file holds {} cases ({}); choose one with --case N",
                    cases.len(),
                    cases.keys().cloned().collect::<Vec<_>>().join(", ")
                ),
            };
            let entry = cases
                .get(&key)
                .ok_or_else(|| anyhow!("no case \"{key}\" in \"cases\""))?
                .as_object()
                .ok_or_else(|| anyhow!("case \"{key}\": expected an object"))?;
            let mut defaults = Map::new();
            if let Some(img) = obj.get("image") {
                let img =
                    img.as_object().ok_or_else(|| anyhow!("\"image\": expected an object"))?;
                for k in ["u0", "v0", "width", "height"] {
                    if let Some(x) = img.get(k) {
                        defaults.insert(k.to_string(), x.clone());
                    }
                }
            }
            if let Some(d) = obj.get("half_baseline_cm") {
                defaults.insert("half_baseline_cm".to_string(), d.clone());
            }
            for (k, x) in entry {
                defaults.insert(k.clone(), x.clone());
            }
            rig_from(&defaults).map_err(|e| anyhow!("case \"{key}\": {e:#}"))
        }
        None => {
            if let Some(n) = case {
                bail!("--case {n} given but the file holds a single rig, not \"cases\"");
            }
            rig_from(obj)
        }
    }
}

/// Walks any JSON value and fails on the first object with a key given twice; the value is
/// the path of the object, for the message.
struct Unique(String);

impl<'de> serde::de::DeserializeSeed<'de> for Unique {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> serde::de::Visitor<'de> for Unique {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("any JSON value")
    }
    fn visit_bool<E>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E>(self) -> Result<(), E> {
        Ok(())
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0usize;
        while seq.next_element_seed(Unique(format!("{}[{i}]", self.0)))?.is_some() {
            i += 1;
        }
        Ok(())
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = std::collections::BTreeSet::new();
        while let Some(k) = map.next_key::<String>()? {
            if !seen.insert(k.clone()) {
                let within = if self.0.is_empty() {
                    "the top-level object".to_string()
                } else {
                    self.0.clone()
                };
                return Err(serde::de::Error::custom(format!(
                    "duplicate key \"{k}\" in {within} (each field once)"
                )));
            }
            map.next_value_seed(Unique(format!(
                "{}\"{k}\"",
                if self.0.is_empty() { String::new() } else { format!("{}.", self.0) }
            )))?;
        }
        Ok(())
    }
}

fn rig_from(obj: &Map<String, Value>) -> Result<Rig> {
    for k in obj.keys() {
        if !(REQUIRED.contains(&k.as_str())
            || OPTIONAL.contains(&k.as_str())
            || IGNORED.contains(&k.as_str()))
        {
            bail!(
                "unknown field \"{k}\" (known: {}, {}; allowed and not read: {})",
                REQUIRED.join(", "),
                OPTIONAL.join(", "),
                IGNORED.join(", ")
            );
        }
    }
    let num = |k: &str| -> Result<Option<f64>> {
        match obj.get(k) {
            None => Ok(None),
            Some(v) => {
                let x = v
                    .as_f64()
                    .ok_or_else(|| anyhow!("field \"{k}\": expected a number, found {v}"))?;
                if !x.is_finite() {
                    bail!("field \"{k}\": not a finite number");
                }
                Ok(Some(x))
            }
        }
    };
    let req = |k: &str| -> Result<f64> { num(k)?.ok_or_else(|| anyhow!("missing field \"{k}\"")) };
    let positive = |k: &str, x: f64| -> Result<f64> {
        if x > 0.0 {
            Ok(x)
        } else {
            bail!("field \"{k}\": must be positive, got {}", crate::fmt::given(x))
        }
    };
    let angle = |k: &str| -> Result<f64> {
        let a = req(k)?;
        if a.abs() >= core::f64::consts::FRAC_PI_2 {
            bail!("field \"{k}\": {a} rad is not a small camera angle (|angle| < pi/2 expected; angles are radians)");
        }
        Ok(a)
    };
    let size = |k: &str, default: u32| -> Result<u32> {
        match obj.get(k) {
            None => Ok(default),
            Some(v) => {
                v.as_u64().filter(|n| (1..=65_535).contains(n)).map(|n| n as u32).ok_or_else(|| {
                    anyhow!("field \"{k}\": expected a whole number of pixels 1..65535, found {v}")
                })
            }
        }
    };
    let phi_u_left = positive("phi_u_left", req("phi_u_left")?)?;
    let phi_u_right = positive("phi_u_right", req("phi_u_right")?)?;
    let phi_v_left = positive("phi_v_left", num("phi_v_left")?.unwrap_or(phi_u_left))?;
    let phi_v_right = positive("phi_v_right", num("phi_v_right")?.unwrap_or(phi_u_right))?;
    let width = size("width", 640)?;
    let height = size("height", 480)?;
    Ok(Rig {
        half_baseline: positive(
            "half_baseline_cm",
            num("half_baseline_cm")?.unwrap_or(HALF_BASELINE_CM),
        )?,
        phi_u_left,
        phi_u_right,
        phi_v_left,
        phi_v_right,
        alpha_left: angle("alpha_left")?,
        alpha_right: angle("alpha_right")?,
        beta0: angle("beta0")?,
        phi0: angle("phi0")?,
        u0: num("u0")?.unwrap_or(width as f64 / 2.0),
        v0: num("v0")?.unwrap_or(height as f64 / 2.0),
        width,
        height,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::sim::presets;

    const CASES: &str = include_str!("../../../shared/tests/fixtures/cases.json");

    #[test]
    fn cases_json_entries_are_the_presets() {
        for n in 1..=4u8 {
            assert_eq!(parse(CASES, Some(n)).unwrap(), presets::case(n).unwrap());
        }
        let e = format!("{:#}", parse(CASES, None).unwrap_err());
        assert!(e.contains("choose one with --case N"), "{e}");
        let e = format!("{:#}", parse(CASES, Some(7)).unwrap_err());
        assert_eq!(e, "no case \"7\" in \"cases\"");
    }

    #[test]
    fn flat_rig_with_defaults() {
        let r = parse(
            r#"{"phi_u_left": 285.836, "phi_u_right": 228.6688, "alpha_left": -0.0455,
                "alpha_right": 0.0455, "beta0": 0.0087, "phi0": 0.0087, "label": "x"}"#,
            None,
        )
        .unwrap();
        assert_eq!(r.phi_v_right, 228.6688);
        assert_eq!((r.u0, r.v0, r.width, r.height), (320.0, 240.0, 640, 480));
        assert_eq!(r.half_baseline, HALF_BASELINE_CM);
        let r = parse(
            r#"{"phi_u_left": 500, "phi_u_right": 500, "phi_v_left": 498, "alpha_left": 0,
                "alpha_right": 0, "beta0": 0, "phi0": 0, "width": 1280, "height": 720,
                "half_baseline_cm": 3.1}"#,
            None,
        )
        .unwrap();
        assert_eq!((r.phi_v_left, r.phi_v_right), (498.0, 500.0));
        assert_eq!((r.u0, r.v0, r.half_baseline), (640.0, 360.0, 3.1));
    }

    #[test]
    fn clear_errors() {
        let base = r#""phi_u_right": 1, "alpha_left": 0, "alpha_right": 0, "beta0": 0, "phi0": 0"#;
        let e = |t: &str| format!("{:#}", parse(t, None).unwrap_err());
        assert_eq!(e(&format!("{{{base}}}")), "missing field \"phi_u_left\"");
        assert_eq!(
            e(&format!("{{\"phi_u_left\": \"a\", {base}}}")),
            "field \"phi_u_left\": expected a number, found \"a\""
        );
        assert_eq!(
            e(&format!("{{\"phi_u_left\": -3, {base}}}")),
            "field \"phi_u_left\": must be positive, got -3"
        );
        assert!(e(&format!("{{\"phi_u_left\": 1, \"u_0\": 3, {base}}}"))
            .starts_with("unknown field \"u_0\""));
        assert!(e(&format!("{{\"phi_u_left\": 1, \"width\": 1.5, {base}}}"))
            .starts_with("field \"width\": expected a whole number"));
        assert!(e(&format!(
            "{{\"phi_u_left\": 1, {}}}",
            base.replace("\"beta0\": 0", "\"beta0\": 45")
        ))
        .starts_with("field \"beta0\": 45 rad is not a small camera angle"));
        assert!(e("[1,2]").starts_with("expected a JSON object"));
        assert!(e(&format!("{{\"phi_u_left\": 1, \"u0\": 320, \"u0\": 100, {base}}}"))
            .starts_with("invalid JSON: duplicate key \"u0\" in the top-level object"),);
        let cases = CASES.replacen("\"beta0\"", "\"beta0\": 1, \"beta0\"", 1);
        let msg = format!("{:#}", parse(&cases, Some(1)).unwrap_err());
        assert!(
            msg.starts_with("invalid JSON: duplicate key \"beta0\" in \"cases\".\"1\""),
            "{msg}"
        );
        assert!(msg.contains(" at line "), "{msg}");
        assert!(e("{").starts_with("invalid JSON"));
        assert!(format!(
            "{:#}",
            parse(&format!("{{\"phi_u_left\": 1, {base}}}"), Some(2)).unwrap_err()
        )
        .contains("single rig"));
    }
}
