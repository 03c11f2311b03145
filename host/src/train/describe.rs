//! What `hvs info` says about a model file (topology, family, frame, matcher geometry,
//! training metadata, input box, fallback), as text: printed by `hvs info` and shown by
//! `hvs view`'s model panel.

use crate::data::model::{self, input_names, output_names, ModelFile};
use std::fmt::Write as _;
use std::path::Path;

/// The lines `hvs info` prints for the checked model file `f` read from `path`.
pub fn describe(path: &Path, f: &ModelFile) -> String {
    let b = &f.blob;
    let mut o = String::new();
    let _ = writeln!(o, "file:        {}", path.display());
    let trailing = f.file_len - f.blob_len;
    let _ = writeln!(
        o,
        "size:        {} bytes (HVSW v{}, payload {} bytes{})",
        f.file_len,
        f.version,
        f.blob_len - hvs_shared::runtime::blob::HEADER_LEN - hvs_shared::runtime::blob::CRC_LEN,
        if trailing > 0 { format!(", {trailing} trailing bytes ignored") } else { String::new() }
    );
    let _ = writeln!(o, "crc:         ok ({:#010x}); all checks passed", f.crc);
    let _ = writeln!(o, "generation:  {}", b.generation);
    let _ = writeln!(
        o,
        "topology:    {} ({} -> {} sigmoid hidden -> {}, {:?} output), {} parameters",
        model::shape(b),
        input_names(b.topology.inputs).join(","),
        b.topology.hidden,
        output_names(b.topology.outputs).join(","),
        b.topology.output_activation,
        b.params.len()
    );
    let _ = writeln!(
        o,
        "family:      {} ({}{}, sigmoid exp: {})",
        b.family.name(),
        match b.family.output_map {
            hvs_shared::runtime::mlp::OutputMap::Direct => "outputs are X, Y, Z in cm",
            hvs_shared::runtime::mlp::OutputMap::InverseDepth =>
                "outputs are X/Z, Y/Z, 1/Z: X = o0/o2, Y = o1/o2, Z = 1/o2",
        },
        match b.family.skip {
            hvs_shared::runtime::blob::Skip::None => "",
            hvs_shared::runtime::blob::Skip::Linear =>
                "; a linear skip term adds an affine map of the inputs",
        },
        b.family.exp.name()
    );
    let _ = writeln!(
        o,
        "frame:       {} ({})",
        b.frame.name(),
        match b.frame {
            hvs_shared::runtime::blob::OutputFrame::Head => "the net gives head-frame points",
            hvs_shared::runtime::blob::OutputFrame::EyePlatform =>
                "the net gives points in the eye platform's frame (the head frame turned by the \
                 neck pan, neck tilt and eye tilt inputs); the model turns them into the head frame",
            hvs_shared::runtime::blob::OutputFrame::Cyclopean =>
                "the net gives points in the cyclopean frame (the eye platform's frame turned by \
                 the version, the mean of the eye pan inputs); the model turns them into the head frame",
        }
    );
    let _ = match b.image_size() {
        Some((w, h)) => writeln!(o, "images:      {w}x{h} px (the training images' size)"),
        None => writeln!(o, "images:      none recorded (trained from points, not images)"),
    };
    let _ = match b.parent() {
        Some((crc, generation)) => writeln!(
            o,
            "parent:      updated from the model with CRC {crc:#010x}, generation {generation}"
        ),
        None => writeln!(o, "parent:      none (trained from scratch)"),
    };
    if let Some(g) = &b.matcher {
        let _ = writeln!(
            o,
            "matcher:     fundamental matrix {:?}, training box {:?} .. {:?} cm, disparities {} .. {} px, right/left image scale {:?}",
            g.fundamental, g.out_min, g.out_max, g.disparity[0], g.disparity[1], g.right_scale
        );
    }
    let m = &b.meta;
    let _ = writeln!(
        o,
        "training:    {}, seed {}, {}, {} points (set hash {:#018x}), train e_ma {} %",
        super::algo_name(m.algorithm),
        m.seed,
        crate::fmt::count(m.restarts as usize, "restart"),
        m.train_points,
        m.train_hash,
        m.train_error_pct
    );
    let _ = writeln!(o, "input box:");
    for (k, name) in input_names(b.topology.inputs).iter().enumerate() {
        let _ = writeln!(
            o,
            "  {name:>13}  {} .. {}",
            b.in_min.get(k).copied().unwrap_or(f32::NAN),
            b.in_max.get(k).copied().unwrap_or(f32::NAN)
        );
    }
    let _ = match &b.fallback {
        Some(c) => writeln!(
            o,
            "fallback:    traditional method, Phi = {} px, d = {} cm, principal point ({}, {})",
            c.phi, c.half_baseline, c.u0, c.v0
        ),
        None => writeln!(o, "fallback:    none (a head would use its built-in calibration)"),
    };
    o
}
