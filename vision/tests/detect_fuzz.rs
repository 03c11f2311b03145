//! Robustness: corrupted, truncated and random image bytes, and odd images, go through
//! `image` decoding and board detection without a panic (an error is fine). Seeded: the same
//! run every time.

use hvs_shared::test_support::splitmix64;
use hvs_vision::board::Board;
use hvs_vision::detect;
use image::{GrayImage, Luma};
use std::path::PathBuf;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        splitmix64(&mut self.0)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn board() -> Board {
    Board::new(9, 6, 1.0).unwrap()
}

fn try_bytes(bytes: &[u8]) -> &'static str {
    match image::load_from_memory(bytes) {
        Err(_) => "undecodable",
        Ok(img) => match detect::detect_image(&img, &board()) {
            Ok(c) => {
                assert_eq!(c.points.len(), 54);
                "detected"
            }
            Err(e) => {
                assert!(!e.to_string().is_empty());
                "refused"
            }
        },
    }
}

#[test]
fn corrupted_fixture_jpegs_never_panic() {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/opencv-stereo/left01.jpg");
    let jpeg = std::fs::read(path).unwrap();
    let mut rng = Rng(2026);
    let mut tally = std::collections::BTreeMap::new();
    for round in 0..40 {
        let mut b = jpeg.clone();
        match round % 4 {
            // Bit flips after the header.
            0 => {
                for _ in 0..1 + rng.below(20) {
                    let k = 200 + rng.below(b.len() - 200);
                    b[k] ^= 1 << rng.below(8);
                }
            }
            // Truncated anywhere.
            1 => b.truncate(rng.below(b.len())),
            // A burst of random bytes.
            2 => {
                let start = rng.below(b.len());
                let len = rng.below(500).min(b.len() - start);
                for x in &mut b[start..start + len] {
                    *x = rng.next() as u8;
                }
            }
            // Pure garbage with a JPEG or PNG magic.
            _ => {
                let magic: &[u8] = if rng.below(2) == 0 {
                    &[0xFF, 0xD8, 0xFF]
                } else {
                    &[0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A]
                };
                b = magic.to_vec();
                b.extend((0..rng.below(4000)).map(|_| rng.next() as u8));
            }
        }
        *tally.entry(try_bytes(&b)).or_insert(0) += 1;
    }
    eprintln!("{tally:?}");
    // The untouched file detects, so the loop did test detection on decodable images.
    assert_eq!(try_bytes(&jpeg), "detected");
}

#[test]
fn odd_images_never_panic() {
    let b = board();
    let mut rng = Rng(7);
    let images = vec![
        GrayImage::new(0, 0),
        GrayImage::new(1, 1),
        GrayImage::new(15, 400),
        GrayImage::from_pixel(16, 16, Luma([255])),
        GrayImage::from_pixel(640, 480, Luma([0])),
        GrayImage::from_fn(640, 480, |_, _| Luma([rng.next() as u8])),
        // A fine checkerboard of 2 px squares, far more corners than a board.
        GrayImage::from_fn(320, 240, |x, y| Luma([if (x / 2 + y / 2) % 2 == 0 { 0 } else { 255 }])),
        // A huge 40x40 checker: the grid is bigger than the board.
        GrayImage::from_fn(640, 480, |x, y| {
            Luma([if (x / 12 + y / 12) % 2 == 0 { 20 } else { 230 }])
        }),
        GrayImage::from_fn(3000, 20, |x, _| Luma([(x % 256) as u8])),
    ];
    for img in &images {
        if let Err(e) = detect::detect(img, &b) {
            eprintln!("{}x{}: {e}", img.width(), img.height());
        }
        let _ = detect::detect_pair(img, img, &b);
    }
    assert!(matches!(
        detect::detect(&images[1], &b),
        Err(detect::DetectError::ImageTooSmall(1, 1))
    ));
    // A 53x40 grid of corners is not a 9 x 6 board.
    assert!(detect::detect(&images[7], &b).is_err());
}
