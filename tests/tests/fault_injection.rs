//! Fault injection on the weight slots, through the boot logic the firmware runs
//! (`hvs_shared::runtime::head::boot` on the raw bytes of both slots):
//!
//! - a model write cut off at every byte offset, as `hvs flash` does it (slot and generation
//!   from `hvs_shared::runtime::slots::plan_write`, bytes from `hvs_host::device::flash_image::with_generation`), with
//!   the rest of the slot erased (0xFF), zero (as QEMU's loader leaves it) or a half-programmed
//!   byte; and an erase cut off at every byte offset;
//! - every single-bit flip of a stored blob, seeded random 2- and 3-bit flips and every 32-bit
//!   burst, with the other slot holding an older model, a newer one or nothing; flips in the
//!   bytes after the blob.
//!
//! After each, the head must run a model that was written completely (the old one or the new
//! one, never a damaged one) or the traditional fallback, `Info` must say which, and its
//! estimates must equal, bit for bit, those of the model it claims to run.

use hvs_host::device::flash_image::with_generation;
use hvs_shared::runtime::blob::{self, ModelBlob, MAX_BLOB_LEN};
use hvs_shared::runtime::head::{self, Boot, Estimator};
use hvs_shared::runtime::layout::Slot;
use hvs_shared::runtime::protocol::{Mode, SlotStatus, Source, StereoPoint};
use hvs_shared::runtime::slots::{plan_write, SlotRequest};
use hvs_shared::runtime::traditional::{traditional_xyz, Calibration};
use hvs_tests::sim::VERSION;
use hvs_tests::{sample_model, sample_posture_model};

/// What should run: a model (its decoded blob and slot) or the fallback.
#[derive(Debug, Clone, PartialEq)]
enum Expect {
    Model(Box<ModelBlob>, Slot),
    Fallback,
}

/// Points inside and outside the training box, and one the fallback cannot solve.
const POINTS: [StereoPoint; 4] = [
    StereoPoint { u_l: 343.0, v_l: 240.0, u_r: 297.0, v_r: 240.0 },
    StereoPoint { u_l: 330.5, v_l: 231.25, u_r: 310.0, v_r: 249.0 },
    StereoPoint { u_l: 20.0, v_l: 470.0, u_r: 5.0, v_r: 470.0 },
    StereoPoint { u_l: 300.0, v_l: 240.0, u_r: 300.0, v_r: 240.0 },
];

/// `bytes` in a slot of `MAX_BLOB_LEN` bytes (what the firmware reads), the rest `fill`.
fn slot_of(bytes: &[u8], fill: u8) -> Vec<u8> {
    let mut s = bytes.to_vec();
    s.resize(MAX_BLOB_LEN, fill);
    s
}

/// Checks that `boot` runs `want`, says so in `Info`, and estimates as `want` does.
fn check_runs(boot: &Boot, want: &Expect, what: &str) {
    let info = boot.info(VERSION);
    match (want, &boot.estimator) {
        (Expect::Model(blob, slot), Estimator::Network(n)) => {
            assert_eq!((n.slot, n.generation), (*slot, blob.generation), "{what}: wrong model");
            assert_eq!(&n.blob, &**blob, "{what}: damaged weights");
            assert_eq!(
                (info.mode, info.slot, info.generation),
                (Mode::Network, Some(*slot), blob.generation),
                "{what}: Info"
            );
            assert_eq!(info.model.map(|m| m.seed), Some(blob.meta.seed), "{what}");
            for p in POINTS {
                let e = boot.estimate(&p).unwrap();
                // A posture-aware model gets the home posture's joint angles (all zero) after
                // the pixels, as `Boot::estimate` feeds it.
                let mut x = p.to_array().to_vec();
                x.resize(blob.n_inputs(), 0.0);
                let mut y = [0f32; 3];
                blob.infer(&x, &mut y).unwrap();
                assert_eq!(
                    [e.x, e.y, e.z].map(f32::to_bits),
                    y.map(f32::to_bits),
                    "{what}: estimate of {p:?}"
                );
                assert_eq!(e.source, Source::Network);
                assert_eq!(
                    e.in_range,
                    blob.in_range(&x) && hvs_shared::runtime::head::outputs_in_range(blob, &x, &y),
                    "{what}"
                );
            }
        }
        (Expect::Fallback, Estimator::Fallback(cal)) => {
            assert_eq!(*cal, Calibration::BUILT_IN, "{what}");
            assert_eq!(
                (info.mode, info.slot, info.model),
                (Mode::Fallback, None, None),
                "{what}: Info"
            );
            for p in POINTS {
                let got = boot.estimate(&p).map(|e| [e.x, e.y, e.z].map(f32::to_bits));
                let want = traditional_xyz(&Calibration::BUILT_IN, &p.to_array())
                    .map(|y| y.map(f32::to_bits));
                assert_eq!(got.is_ok(), want.is_ok(), "{what}: {p:?}");
                if let (Ok(g), Ok(w)) = (got, want) {
                    assert_eq!(g, w, "{what}: fallback estimate of {p:?}");
                }
            }
        }
        (w, got) => panic!("{what}: expected {w:?}, runs {got:?}"),
    }
}

/// What a slot holding `bytes` must run as, if anything: the blob if the bytes start with a
/// complete, intact copy of one of `written`.
fn intact<'a>(bytes: &[u8], written: &'a [Vec<u8>]) -> Option<&'a Vec<u8>> {
    written.iter().find(|w| bytes.starts_with(w))
}

/// The model the pair of slots must run: the intact one with the higher generation (A on a
/// tie), or the fallback. `written` are the complete blobs ever written.
fn expected(a: &[u8], b: &[u8], written: &[Vec<u8>]) -> Expect {
    let gen = |s: &[u8]| intact(s, written).map(|w| blob::decode(w).unwrap());
    match (gen(a), gen(b)) {
        (Some(x), Some(y)) if y.generation > x.generation => Expect::Model(Box::new(y), Slot::B),
        (Some(x), _) => Expect::Model(Box::new(x), Slot::A),
        (None, Some(y)) => Expect::Model(Box::new(y), Slot::B),
        (None, None) => Expect::Fallback,
    }
}

/// Slot contents before a write: (name, A, B). Blobs are complete; "damaged" is a blob with
/// a flipped bit.
fn before_states() -> Vec<(&'static str, Vec<u8>, Vec<u8>)> {
    let m = |generation: u32, seed: u64| hvs_tests::blob_bytes(&sample_model(generation, seed));
    let mut damaged = m(6, 13);
    damaged[40] ^= 0x04;
    vec![
        ("both empty", vec![], vec![]),
        ("A gen 1, B empty", m(1, 11), vec![]),
        ("A empty, B gen 2", vec![], m(2, 12)),
        ("A gen 5, B gen 4", m(5, 15), m(4, 14)),
        ("A gen 3, B gen 7", m(3, 13), m(7, 17)),
        ("A gen 7, B damaged", m(7, 17), damaged),
    ]
}

fn boot_slots(a: &[u8], b: &[u8]) -> Boot {
    head::boot(a, b)
}

#[test]
fn write_cut_off_at_every_byte_boots_the_old_or_the_new_model() {
    let mut boots = 0usize;
    // A 4-5-3 model, then the larger posture-aware 9-8-3 one, written over each state.
    let news = [sample_model(1, 99), sample_posture_model(1, 98)];
    for (name, a, b, new_model) in before_states()
        .into_iter()
        .flat_map(|(n, a, b)| news.iter().map(move |m| (n, a.clone(), b.clone(), m)))
    {
        let written_before: Vec<Vec<u8>> =
            [&a, &b].into_iter().filter(|s| blob::decode(s).is_ok()).cloned().collect();
        let (sa, sb) = (slot_of(&a, 0xFF), slot_of(&b, 0xFF));
        let before = expected(&sa, &sb, &written_before);
        check_runs(&boot_slots(&sa, &sb), &before, name);

        let plan = plan_write(
            hvs_shared::runtime::head::slot_state(&sa),
            hvs_shared::runtime::head::slot_state(&sb),
            SlotRequest::Auto,
        )
        .unwrap();
        // The plan never targets the running slot.
        if let Expect::Model(_, running) = &before {
            assert_ne!(plan.slot, *running, "{name}");
        }
        let new = with_generation(new_model, plan.generation).unwrap();
        let mut written = written_before.clone();
        written.push(new.clone());
        let place = |target: Vec<u8>| match plan.slot {
            Slot::A => (target, sb.clone()),
            Slot::B => (sa.clone(), target),
        };
        let old_target = match plan.slot {
            Slot::A => &a,
            Slot::B => &b,
        };

        // Erase cut off: the first k bytes of the old contents already 0xFF.
        for k in 0..=old_target.len() {
            let mut t = slot_of(old_target, 0xFF);
            t[..k].fill(0xFF);
            let (x, y) = place(t);
            let what = format!("{name}: erase of {:?} cut at byte {k}", plan.slot);
            let want = expected(&x, &y, &written_before);
            assert_eq!(want, before, "{what}: the running model is not touched");
            check_runs(&boot_slots(&x, &y), &want, &what);
            boots += 1;
        }

        // Programming cut off after k bytes; the rest erased (0xFF), zero (QEMU) or a
        // half-programmed byte at k (flash programming only clears bits: new | 0x0F).
        for k in 0..=new.len() {
            let mut torn = new[..k].to_vec();
            if let Some(&next) = new.get(k) {
                torn.push(next | 0x0F);
            }
            for (fill, target) in [
                ("0xFF", slot_of(&new[..k], 0xFF)),
                ("0x00", slot_of(&new[..k], 0x00)),
                ("torn", slot_of(&torn, 0xFF)),
            ] {
                let (x, y) = place(target);
                let what = format!(
                    "{name}: write of gen {} to {:?} cut at byte {k}/{} ({fill})",
                    plan.generation,
                    plan.slot,
                    new.len()
                );
                let want = expected(&x, &y, &written);
                let complete =
                    if plan.slot == Slot::A { x.starts_with(&new) } else { y.starts_with(&new) };
                if complete {
                    assert_eq!(
                        want,
                        Expect::Model(Box::new(blob::decode(&new).unwrap()), plan.slot),
                        "{what}"
                    );
                } else {
                    assert_eq!(want, before, "{what}: an incomplete write changes nothing");
                }
                check_runs(&boot_slots(&x, &y), &want, &what);
                boots += 1;
            }
        }
        // The complete write runs the new model.
        let (x, y) = place(slot_of(&new, 0xFF));
        check_runs(
            &boot_slots(&x, &y),
            &Expect::Model(Box::new(blob::decode(&new).unwrap()), plan.slot),
            &format!("{name}: complete write"),
        );
    }
    // Six states x two new models x (erase offsets + 3 x write offsets).
    eprintln!("write cut-off: {boots} boots checked");
    assert!(boots > 6 * 3 * (300 + 600), "only {boots} boots");
}

/// Boots `damaged` in `slot` with `other` in the other slot and checks the damaged blob is
/// never run.
fn check_damaged(damaged: &[u8], slot: Slot, other: &[u8], intact_blobs: &[Vec<u8>], what: &str) {
    let (a, b) = match slot {
        Slot::A => (slot_of(damaged, 0xFF), slot_of(other, 0xFF)),
        Slot::B => (slot_of(other, 0xFF), slot_of(damaged, 0xFF)),
    };
    let boot = boot_slots(&a, &b);
    let status = match slot {
        Slot::A => boot.slot_a,
        Slot::B => boot.slot_b,
    };
    assert!(
        matches!(status, SlotStatus::Empty | SlotStatus::Invalid(_)),
        "{what}: damaged slot classified {status:?}"
    );
    check_runs(&boot, &expected(&a, &b, intact_blobs), what);
}

/// The stored blob under test and the other slot's contents: (name, stored, slot, other).
fn flip_scenarios() -> Vec<(&'static str, Vec<u8>, Slot, Vec<u8>)> {
    let m = |generation: u32, seed: u64| hvs_tests::blob_bytes(&sample_model(generation, seed));
    let pm =
        |generation: u32, seed: u64| hvs_tests::blob_bytes(&sample_posture_model(generation, seed));
    vec![
        ("posture-aware A alone", pm(5, 27), Slot::A, vec![]),
        ("posture-aware B gen 6, A gen 2", pm(6, 28), Slot::B, m(2, 29)),
        ("A alone", m(5, 21), Slot::A, vec![]),
        ("A gen 5, B gen 4", m(5, 21), Slot::A, m(4, 22)),
        ("B gen 9, A gen 3", m(9, 23), Slot::B, m(3, 24)),
        ("B gen 2, A gen 8", m(2, 25), Slot::B, m(8, 26)),
    ]
}

/// The intact blobs of a scenario: the stored one and the other slot's, if any.
fn intact_blobs_of(stored: &[u8], other: &[u8]) -> Vec<Vec<u8>> {
    [stored, other].into_iter().filter(|s| !s.is_empty()).map(<[u8]>::to_vec).collect()
}

#[test]
fn every_single_bit_flip_is_refused() {
    let mut flips = 0usize;
    for (name, stored, slot, other) in flip_scenarios() {
        let intact_blobs = intact_blobs_of(&stored, &other);
        for bit in 0..stored.len() * 8 {
            let mut d = stored.clone();
            d[bit / 8] ^= 1 << (bit % 8);
            let what = format!("{name}: bit {bit} (byte {}) flipped", bit / 8);
            check_damaged(&d, slot, &other, &intact_blobs, &what);
            flips += 1;
        }
    }
    eprintln!("single-bit flips: {flips} boots checked");
    assert_eq!(flips, flip_scenarios().iter().map(|s| s.1.len() * 8).sum::<usize>());
}

#[test]
fn multi_bit_flips_and_bursts_are_refused() {
    // Seeded xorshift: the same flips every run.
    let mut s: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    for (name, stored, slot, other) in flip_scenarios() {
        let intact_blobs = intact_blobs_of(&stored, &other);
        let bits = stored.len() * 8;
        // 2 and 3 distinct bits (CRC-32 detects all of these at this length).
        for n in [2usize, 3] {
            for _ in 0..500 {
                let mut d = stored.clone();
                let mut picked = Vec::new();
                while picked.len() < n {
                    let b = (next() % bits as u64) as usize;
                    if !picked.contains(&b) {
                        picked.push(b);
                    }
                }
                for &b in &picked {
                    d[b / 8] ^= 1 << (b % 8);
                }
                check_damaged(&d, slot, &other, &intact_blobs, &format!("{name}: bits {picked:?}"));
            }
        }
        // Every burst of at most 32 bits: a random non-zero 32-bit pattern at every offset.
        for start in 0..stored.len() {
            let pattern = (next() as u32 | 1).to_le_bytes();
            let mut d = stored.clone();
            for (i, p) in pattern.iter().enumerate() {
                if let Some(x) = d.get_mut(start + i) {
                    *x ^= p;
                }
            }
            check_damaged(&d, slot, &other, &intact_blobs, &format!("{name}: burst at {start}"));
        }
    }
}

#[test]
fn bytes_after_the_blob_do_not_matter() {
    let stored = hvs_tests::blob_bytes(&sample_model(4, 31));
    let want = Expect::Model(Box::new(blob::decode(&stored).unwrap()), Slot::A);
    for fill in [0x00u8, 0xFF, 0xA5] {
        let slot = slot_of(&stored, fill);
        for pos in (stored.len()..MAX_BLOB_LEN).step_by(97) {
            for bit in 0..8 {
                let mut s = slot.clone();
                s[pos] ^= 1 << bit;
                check_runs(
                    &boot_slots(&s, &[]),
                    &want,
                    &format!("fill {fill:#x}, bit {bit} of byte {pos}"),
                );
            }
        }
    }
}
