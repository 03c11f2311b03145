//! Image files: grey images in (PNG or JPEG, bounded in size before decoding), PNG bytes out,
//! and a rendered capture set written as the files `hvs board detect` reads.

use crate::data::captures::{captures_csv, CaptureRow};
use crate::data::output::Batch;
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use hvs_vision::render;
use image::GrayImage;
use std::io::Cursor;
use std::path::Path;

/// Reads an image file (PNG or JPEG, any colour type) as grey levels, through
/// [`hvs_vision::image_file`]: other formats and images over
/// [`hvs_vision::image_file::MAX_PIXELS`] are refused before decoding; errors name the file.
pub fn read_grey(path: &Path) -> Result<GrayImage> {
    hvs_vision::image_file::read_grey(path).map_err(|e| anyhow!("{e}"))
}

/// Reads a left and a right image of the same size as grey levels.
pub fn read_pair(left: &Path, right: &Path) -> Result<(GrayImage, GrayImage)> {
    // Both decoded at once when there are two cores (PNG decoding is some 12 ms of `hvs depth` on the 741x500 Motorcycle pair);
    // the left image's error first, as when read one after the other.
    let (l, r) = rayon::join(|| read_grey(left), || read_grey(right));
    let (l, r) = (l?, r?);
    if l.dimensions() != r.dimensions() {
        bail!(
            "{} and {}: the images differ in size ({}x{} and {}x{})",
            left.display(),
            right.display(),
            l.width(),
            l.height(),
            r.width(),
            r.height()
        );
    }
    Ok((l, r))
}

/// Refuses a left and a right image of different sizes (every command that matches a pair).
pub fn check_same_size(left: &GrayImage, right: &GrayImage) -> Result<()> {
    if left.dimensions() != right.dimensions() {
        bail!(
            "the images differ in size: left {}x{}, right {}x{}",
            left.width(),
            left.height(),
            right.width(),
            right.height()
        );
    }
    Ok(())
}

/// PNG bytes of an image (written with the one atomic writer by the caller).
pub fn png_bytes<P, C>(img: &image::ImageBuffer<P, C>) -> Result<Vec<u8>>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| anyhow!("cannot encode a PNG: {e}"))?;
    Ok(out.into_inner())
}

/// PNG bytes for the screen: the fast deflate level with adaptive row filters, about 0.5 ms for
/// a 640x480 grey frame where [`png_bytes`]'s default level takes about 7.5 ms, for files
/// about 12 % larger (what `hvs view` serves; files on disk keep [`png_bytes`]).
pub fn png_bytes_fast<P, C>(img: &image::ImageBuffer<P, C>) -> Result<Vec<u8>>
where
    P: image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
    C: std::ops::Deref<Target = [P::Subpixel]>,
{
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let mut out = Vec::new();
    img.write_with_encoder(PngEncoder::new_with_quality(
        &mut out,
        CompressionType::Fast,
        FilterType::Adaptive,
    ))
    .map_err(|e| anyhow!("cannot encode a PNG: {e}"))?;
    Ok(out)
}

/// One rendered scene pair into `dir` (created if missing): left.png, right.png and its truth
/// in the formats `hvs depth` writes (`SceneRender::truth_images`: depth.pfm, matches.pfm),
/// replaced all together ([`Batch`]). Returns how many left pixels the right camera sees.
pub fn write_scene_pair(dir: &Path, r: &hvs_vision::scene::SceneRender) -> Result<usize> {
    let (depth, matches) = r.truth_images();
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let bytes = [
        png_bytes(&r.left)?,
        png_bytes(&r.right)?,
        hvs_vision::pfm::pfm_bytes(&depth),
        hvs_vision::pfm::pfm_bytes(&matches),
    ];
    let batch = Batch::new();
    for (name, b) in SCENE_PAIR_FILES.iter().zip(&bytes) {
        batch.add(&dir.join(name), b)?;
    }
    batch.commit()?;
    Ok(matches.data.chunks_exact(3).filter(|m| m[2] > 0.0).count())
}

/// The files [`write_scene_pair`] writes, in its order.
pub const SCENE_PAIR_FILES: [&str; 4] = ["left.png", "right.png", "depth.pfm", "matches.pfm"];

/// Writes a rendered capture set into `dir` (created if missing), replaced all together
/// ([`Batch`]: a rerun stopped half-way never leaves new images beside the last run's
/// `board.json`): the
/// PNG pairs, `captures.csv` ([`captures_csv`], with the joint columns when `joints` is
/// given), `truth.csv` and `board.json`, which is
/// what `hvs board detect` reads.
pub fn write_capture_set(
    dir: &Path,
    set: &render::RenderedSet,
    joints: Option<&Joints>,
) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))?;
    let batch = Batch::new();
    for c in &set.captures {
        batch.add(&dir.join(&c.left_name), &png_bytes(&c.render.left)?)?;
        batch.add(&dir.join(&c.right_name), &png_bytes(&c.render.right)?)?;
    }
    let rows: Vec<CaptureRow<'_>> = set
        .captures
        .iter()
        .map(|c| CaptureRow {
            left: &c.left_name,
            right: &c.right_name,
            centre: c.centre,
            joints: joints.copied().unwrap_or(Joints::HOME),
        })
        .collect();
    let texts = [captures_csv(&rows, joints.is_some()), set.truth_csv(), set.board_json()];
    for (name, text) in CAPTURE_SET_TEXTS.iter().zip(texts) {
        batch.add(&dir.join(name), text.as_bytes())?;
    }
    batch.commit()
}

/// The text files [`write_capture_set`] writes beside the images, in its order.
const CAPTURE_SET_TEXTS: [&str; 3] = ["captures.csv", "truth.csv", "board.json"];

/// The names of the files [`write_capture_set`] writes for a set of `pairs` pairs: the
/// images ([`render::capture_names`]) and `captures.csv`, `truth.csv`, `board.json`, so that a command can
/// check them against its inputs before rendering.
pub fn capture_set_files(pairs: usize) -> Vec<String> {
    (0..pairs).flat_map(render::capture_names).chain(CAPTURE_SET_TEXTS.map(String::from)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::sim::presets;
    use hvs_vision::board::Board;

    /// Two clean pairs of the OpenCV board at (1, -2, 65 | 85) cm through case I at home.
    fn two_pairs() -> render::RenderedSet {
        render::render_capture_set(
            &hvs_shared::sim::posture::HeadRig::new(presets::CASE_1),
            &Joints::HOME,
            &render::opencv_board(),
            [1.0, -2.0],
            &[65.0, 85.0],
            &render::RenderOptions::clean(),
            0,
        )
        .unwrap()
    }

    #[test]
    fn capture_set_files_are_the_files_written() {
        let set = two_pairs();
        let dir = tempfile::tempdir().unwrap();
        write_capture_set(dir.path(), &set, None).unwrap();
        let mut written: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        written.sort();
        let mut listed = capture_set_files(2);
        listed.sort();
        assert_eq!(written, listed);
    }

    #[test]
    fn capture_set_files_are_what_board_detect_reads() {
        let set = two_pairs();
        let dir = tempfile::tempdir().unwrap();
        let with_joints = dir.path().join("joints");
        let j = Joints([1.5, -2.0, 0.0, 3.0, -3.0]);
        write_capture_set(&with_joints, &set, Some(&j)).unwrap();
        let with = std::fs::read_to_string(with_joints.join("captures.csv")).unwrap();
        assert_eq!(
            with.lines().next(),
            Some("left,right,z,x,y,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan")
        );
        assert_eq!(with.lines().nth(1), Some("left01.png,right01.png,65,1,-2,1.5,-2,0,3,-3"));

        let out = dir.path().join("shots");
        write_capture_set(&out, &set, None).unwrap();
        assert_eq!(
            std::fs::read_to_string(out.join("captures.csv")).unwrap(),
            "left,right,z,x,y\nleft01.png,right01.png,65,1,-2\nleft02.png,right02.png,85,1,-2\n"
        );
        let read = crate::data::captures::read(&out.join("captures.csv")).unwrap();
        assert_eq!(read.captures.len(), 2);
        assert_eq!((read.captures[1].z, read.captures[1].xy), (Some(85.0), [1.0, -2.0]));
        assert_eq!(read_grey(&read.captures[0].left).unwrap(), set.captures[0].render.left);
        let board = std::fs::read_to_string(out.join("board.json")).unwrap();
        assert_eq!(Board::from_json(&board).unwrap(), set.board);
        assert_eq!(std::fs::read_to_string(out.join("truth.csv")).unwrap(), set.truth_csv());
        // Writing names the file that failed.
        let blocked = dir.path().join("file");
        std::fs::write(&blocked, "").unwrap();
        let err = write_capture_set(&blocked, &set, None).unwrap_err();
        let err = format!("{err:#}");
        assert!(err.contains(&blocked.display().to_string()), "{err}");
    }
}
