//! Writes the seed corpora of the fuzz targets (valid inputs the fuzzer mutates from):
//! `cargo run -p hvs-tests --example fuzz_seeds -- fuzz/corpus`. Deterministic: the same
//! files every run. Layout: `DIR/<target>/<name>`, as `cargo fuzz run <target>` reads them.

use hvs_shared::blob::{CRC_LEN, HEADER_LEN};
use hvs_shared::protocol::{self, Request, RequestBody, StereoPoint, MAX_FRAME_LEN};
use std::path::Path;

fn frame(req: &Request) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    match protocol::encode_request(req, &mut buf) {
        Ok(f) => f.to_vec(),
        Err(e) => panic!("encoding {req:?}: {e}"),
    }
}

fn write(dir: &Path, target: &str, name: &str, bytes: &[u8]) -> std::io::Result<()> {
    let d = dir.join(target);
    std::fs::create_dir_all(&d)?;
    let tmp = d.join(format!(".{name}.tmp"));
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, d.join(name))
}

fn main() {
    let Some(dir) = std::env::args().nth(1) else {
        eprintln!("usage: fuzz_seeds DIR   (e.g. fuzz/corpus)");
        std::process::exit(2);
    };
    if let Err(e) = run(Path::new(&dir)) {
        eprintln!("error: {dir}: {e}");
        std::process::exit(1);
    }
}

fn run(dir: &Path) -> std::io::Result<()> {
    let blob = hvs_tests::blob_bytes(&hvs_tests::sample_model(3, 42));
    // blob_decode: the raw blob (first byte 'H' is even: used raw), and its payload alone
    // (odd first byte: wrapped under a correct header and CRC by the target).
    write(dir, "blob_decode", "valid_blob", &blob)?;
    let mut payload = vec![1u8];
    payload.extend_from_slice(&blob[HEADER_LEN..blob.len() - CRC_LEN]);
    write(dir, "blob_decode", "valid_payload", &payload)?;

    let p = StereoPoint {
        u_l: 340.0,
        v_l: 236.0,
        u_r: 300.0,
        v_r: 236.0,
    };
    let bodies = [
        ("ping", RequestBody::Ping),
        ("info", RequestBody::Info),
        ("estimate", RequestBody::Estimate(p)),
        ("look", RequestBody::Look(p)),
        ("home", RequestBody::Home),
        (
            "bench",
            RequestBody::Bench {
                point: p,
                count: 10,
            },
        ),
    ];
    let mut stream = Vec::new();
    for (k, (name, body)) in bodies.iter().enumerate() {
        let f = frame(&Request {
            id: k as u32 + 1,
            body: *body,
        });
        write(dir, "frame_decode", name, &f)?;
        stream.extend_from_slice(&f);
    }
    write(dir, "frame_decode", "stream", &stream)?;

    // head_stream: mode (bit 0-1 slots, bit 2 structured), ticks per frame, then the input.
    let looks: Vec<u8> = [
        RequestBody::Look(p),
        RequestBody::Look(StereoPoint {
            u_l: 250.0,
            u_r: 220.0,
            ..p
        }),
        RequestBody::Home,
        RequestBody::Estimate(p),
    ]
    .iter()
    .enumerate()
    .flat_map(|(k, body)| {
        frame(&Request {
            id: k as u32 + 1,
            body: *body,
        })
    })
    .collect();
    for (name, mode) in [
        ("fallback_raw", 0u8),
        ("network_a_raw", 1),
        ("network_b_raw", 2),
    ] {
        let mut v = vec![mode, 20];
        v.extend_from_slice(&looks);
        write(dir, "head_stream", name, &v)?;
    }
    let mut structured = vec![5u8, 30];
    for (kind, q) in [
        (0u8, p),
        (0, StereoPoint { u_l: 200.0, ..p }),
        (2, p),
        (1, p),
    ] {
        structured.push(kind);
        for c in q.to_array() {
            structured.extend_from_slice(&c.to_le_bytes());
        }
    }
    write(dir, "head_stream", "network_structured", &structured)?;
    Ok(())
}
