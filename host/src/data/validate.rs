//! Checks a training set before any training: refuses sets that cannot determine the net
//! (fewer equations, rows x outputs, than the net has parameters), sets that hold a single
//! depth, and values no camera or head produces, naming the row and column ([`plausible_values`],
//! which also guards the points of `hvs predict` and `hvs eval`).

use crate::data::csv::Table;
use crate::data::dataset::{JOINT_COLUMNS, PIXEL_COLUMNS, TARGET_COLUMNS};
use anyhow::{bail, Result};
use hvs_shared::runtime::mlp::param_count;

/// Largest |pixel| a camera reports (px): far beyond any sensor, far below f32 trouble.
pub const MAX_ABS_PIXEL: f64 = 1e5;
/// Largest |x|, |y| and z of a point (cm): a kilometre, the bound of every scene and board
/// description too (one definition, in `hvs-vision`).
pub const MAX_ABS_CM: f64 = hvs_vision::invalid::MAX_CM;
/// How far (px) a pixel may lie beyond its image's border pixels' centres: the pixel's own
/// half width and a little more for a corner found on the border.
pub const EDGE_SLACK_PX: f64 = 1.0;
/// Largest |joint angle| (degrees).
pub const MAX_ABS_DEG: f64 = 360.0;

/// Checks `table` as the training set of a net with `hidden` units and `outputs` outputs.
pub fn training_set(table: &Table, hidden: usize, outputs: usize) -> Result<()> {
    plausible_values(table)?;
    let d = &table.data;
    let file = table.name();
    let ni = d.n_inputs;
    let params = param_count(ni, hidden, outputs);
    let equations = d.len() * outputs;
    if equations < params {
        bail!(
            "{file}: {} x {outputs} outputs = {equations} equations cannot determine the \
             {ni}-{hidden}-{outputs} net's {params} parameters; give at least {} rows (or fewer --hidden units)",
            crate::fmt::count(d.len(), "row"),
            params.div_ceil(outputs)
        );
    }
    let z0 = d.targets.first().map(|t| t[2]);
    if let Some(z0) = z0 {
        if d.targets.iter().all(|t| t[2] == z0) {
            bail!(
                "{file}: all {} rows lie at one depth (z = {z0} cm): a net cannot learn depth \
                 from one depth; give boards at two or more depths",
                d.len()
            );
        }
    }
    Ok(())
}

/// Checks that every pixel, joint angle and position of `table` is a value a camera head
/// produces (the value checks of [`training_set`], without its row counts: `hvs train --from`
/// takes one board at one depth), and, where the file gives the images' size
/// (`image_width`, `image_height`), that every pixel lies in its image (a pixel's centre at
/// `0..=w-1`; within [`EDGE_SLACK_PX`] of the border).
pub fn plausible_values(table: &Table) -> Result<()> {
    let d = &table.data;
    for r in 0..d.len() {
        for (c, &v) in d.row(r).iter().enumerate() {
            let (name, limit, unit) = if c < PIXEL_COLUMNS.len() {
                (PIXEL_COLUMNS[c], MAX_ABS_PIXEL, "px")
            } else {
                (JOINT_COLUMNS[c - PIXEL_COLUMNS.len()], MAX_ABS_DEG, "degrees")
            };
            if v.abs() > limit {
                bail!(
                    "{}: column \"{name}\": {} {unit} is not a value a camera head produces (|{name}| must be at most {limit})",
                    table.at(r),
                    crate::fmt::given(v)
                );
            }
            if let (Some((w, h)), true) = (table.image_size, c < PIXEL_COLUMNS.len()) {
                let size = f64::from(if c % 2 == 0 { w } else { h });
                if !(-EDGE_SLACK_PX..=size - 1.0 + EDGE_SLACK_PX).contains(&v) {
                    bail!(
                        "{}: column \"{name}\": {v} px lies outside the {w}x{h} px images the file's {} and {} columns give",
                        table.at(r),
                        crate::data::csv::IMAGE_SIZE_COLUMNS[0],
                        crate::data::csv::IMAGE_SIZE_COLUMNS[1]
                    );
                }
            }
        }
        if let Some(t) = d.targets.get(r) {
            for (k, &v) in t.iter().enumerate() {
                if v.abs() > MAX_ABS_CM {
                    bail!(
                        "{}: column \"{}\": {} cm is not a position a camera sees (|{}| must be at most {MAX_ABS_CM} cm)",
                        table.at(r),
                        TARGET_COLUMNS[k],
                        crate::fmt::given(v),
                        TARGET_COLUMNS[k]
                    );
                }
            }
        }
    }
    Ok(())
}
