//! Writes the seeded 4-5-3 sample blob of the QEMU tests to a file (for `firmware/measure.sh`
//! until a trained model is at hand): `cargo run -p hvs-tests --example sample_blob -- OUT
//! [GENERATION [POSTURE_HIDDEN [default] | default]]`; with POSTURE_HIDDEN, a posture-aware
//! 9-POSTURE_HIDDEN-3 one (thesis family; with `default` after it, in the default family of
//! `hvs train`); with `default` alone, the 4-5-3 in the default family.

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(out) = args.next() else {
        eprintln!("usage: sample_blob OUT [GENERATION [POSTURE_HIDDEN]]");
        std::process::exit(2);
    };
    let generation = match args.next().map(|g| g.parse::<u32>()) {
        None => 1,
        Some(Ok(g)) => g,
        Some(Err(e)) => {
            eprintln!("error: GENERATION: {e}");
            std::process::exit(2);
        }
    };
    let blob = match args.next().map(|h| if h == "default" { Ok(0) } else { h.parse::<u8>() }) {
        None => hvs_tests::sample_model(generation, 42),
        Some(Ok(0)) => hvs_tests::sample_default_model(generation, 42),
        Some(Ok(h @ 1..=32)) => match args.next().as_deref() {
            None => hvs_tests::sample_posture_model_hidden(generation, 42, h),
            Some("default") => hvs_tests::sample_default_posture_model(generation, 42, h),
            Some(other) => {
                eprintln!("error: after POSTURE_HIDDEN only `default`, got {other}");
                std::process::exit(2);
            }
        },
        Some(_) => {
            eprintln!("error: POSTURE_HIDDEN: a hidden unit count 1..=32");
            std::process::exit(2);
        }
    };
    let mut buf = vec![0u8; hvs_shared::runtime::blob::MAX_BLOB_LEN];
    let n = match blob.encode(&mut buf) {
        Ok(n) => n,
        Err(e) => {
            eprintln!("error: encoding the sample blob: {e}");
            std::process::exit(1);
        }
    };
    let tmp = format!("{out}.tmp");
    if let Err(e) = std::fs::write(&tmp, &buf[..n]).and_then(|_| std::fs::rename(&tmp, &out)) {
        eprintln!("error: {out}: {e}");
        std::process::exit(1);
    }
}
