//! Writes the seed corpora of the fuzz targets (`hvs_tests::fuzz::seeds`):
//! `cargo run -p hvs-tests --example fuzz_seeds -- fuzz/corpus`. Deterministic: the same
//! files every run. Layout: `DIR/<target>/<name>`, as `cargo fuzz run <target>` reads them.

use std::path::Path;

fn main() {
    let Some(dir) = std::env::args().nth(1) else {
        eprintln!("usage: fuzz_seeds DIR   (e.g. fuzz/corpus)");
        std::process::exit(2);
    };
    for (target, name, bytes) in hvs_tests::fuzz::seeds() {
        let d = Path::new(&dir).join(target);
        let tmp = d.join(format!(".{name}.tmp"));
        let r = std::fs::create_dir_all(&d)
            .and_then(|_| std::fs::write(&tmp, &bytes))
            .and_then(|_| std::fs::rename(&tmp, d.join(name)));
        if let Err(e) = r {
            eprintln!("error: {}: {e}", d.join(name).display());
            std::process::exit(1);
        }
    }
}
