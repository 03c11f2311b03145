//! Real cameras: the `--cameras v4l:LEFT,RIGHT` spec, the camera pixel formats turned into
//! grey levels, and (with the `v4l` cargo feature) two V4L2 devices as a [`FrameSource`].
//!
//! Everything but the device I/O is compiled and tested without the feature: the spec, the
//! conversions (GREY, YUYV, UYVY, RGB3, BGR3, MJPG) with their checks of a frame's size, and
//! the message of a build without V4L2. The devices are opened with the model's image size;
//! a driver that gives another size is refused (the model's pixels would mean something
//! else). The two cameras are grabbed back to back: without a hardware trigger their frames
//! are up to one frame period apart.

#[cfg(feature = "v4l")]
mod v4l;

use super::frames::FrameSource;
use anyhow::{anyhow, bail, Result};
use image::GrayImage;
use std::path::PathBuf;

/// The two cameras of `--cameras v4l:LEFT,RIGHT`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CameraSpec {
    /// The left camera's device.
    pub left: PathBuf,
    /// The right camera's device.
    pub right: PathBuf,
}

impl CameraSpec {
    /// Parses `v4l:A,B`: each of `A`, `B` a device path (`/dev/video0`) or a device number
    /// (`0` is `/dev/video0`); the two must differ.
    pub fn parse(s: &str) -> Result<CameraSpec> {
        let Some(rest) = s.strip_prefix("v4l:") else {
            bail!("--cameras: expected v4l:LEFT,RIGHT (device paths or numbers), got {s:?}");
        };
        let parts: Vec<&str> = rest.split(',').map(str::trim).collect();
        let [l, r] = parts.as_slice() else {
            bail!("--cameras: expected two devices after v4l:, got {s:?}");
        };
        let device = |p: &str| -> Result<PathBuf> {
            if p.is_empty() {
                bail!("--cameras: an empty device in {s:?}");
            }
            Ok(match p.parse::<u32>() {
                Ok(n) => PathBuf::from(format!("/dev/video{n}")),
                Err(_) => PathBuf::from(p),
            })
        };
        let (left, right) = (device(l)?, device(r)?);
        if left == right {
            bail!("--cameras: the left and right cameras are the same device ({})", left.display());
        }
        Ok(CameraSpec { left, right })
    }
}

/// A camera pixel format this module reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    /// 8-bit grey levels (`GREY`).
    Grey,
    /// YUV 4:2:2, `Y0 U Y1 V` (`YUYV`): the luma is the grey level.
    Yuyv,
    /// YUV 4:2:2, `U Y0 V Y1` (`UYVY`).
    Uyvy,
    /// 24-bit RGB (`RGB3`).
    Rgb,
    /// 24-bit BGR (`BGR3`).
    Bgr,
    /// Motion JPEG (`MJPG`): one JPEG per frame.
    Mjpeg,
}

impl PixelFormat {
    /// The formats in the order they are asked of a camera (the cheapest to read first).
    pub const PREFERRED: [PixelFormat; 6] = [
        PixelFormat::Grey,
        PixelFormat::Yuyv,
        PixelFormat::Uyvy,
        PixelFormat::Mjpeg,
        PixelFormat::Rgb,
        PixelFormat::Bgr,
    ];

    /// The V4L2 four-character code.
    pub fn fourcc(self) -> [u8; 4] {
        match self {
            PixelFormat::Grey => *b"GREY",
            PixelFormat::Yuyv => *b"YUYV",
            PixelFormat::Uyvy => *b"UYVY",
            PixelFormat::Rgb => *b"RGB3",
            PixelFormat::Bgr => *b"BGR3",
            PixelFormat::Mjpeg => *b"MJPG",
        }
    }

    /// The format of a four-character code, `None` for one this module does not read.
    pub fn from_fourcc(code: [u8; 4]) -> Option<PixelFormat> {
        PixelFormat::PREFERRED.into_iter().find(|f| f.fourcc() == code)
    }

    /// Bytes per pixel of the uncompressed formats (`None` for MJPG).
    fn bytes_per_pixel(self) -> Option<usize> {
        match self {
            PixelFormat::Grey => Some(1),
            PixelFormat::Yuyv | PixelFormat::Uyvy => Some(2),
            PixelFormat::Rgb | PixelFormat::Bgr => Some(3),
            PixelFormat::Mjpeg => None,
        }
    }
}

/// The grey levels of one camera frame: `data` in `format`, `width x height` pixels, rows
/// `stride` bytes apart (uncompressed formats; `0`: packed). Colour becomes grey as a
/// colour photo read by `hvs` does (`image`'s luma of RGB); YUV's luma is taken as it is.
/// A frame shorter than its size says, or a JPEG of another size, is an error.
pub fn grey_frame(
    format: PixelFormat,
    width: u32,
    height: u32,
    stride: usize,
    data: &[u8],
) -> Result<GrayImage> {
    let (w, h) = (width as usize, height as usize);
    if w == 0 || h == 0 {
        bail!("a frame of {width}x{height} pixels is empty");
    }
    let Some(bpp) = format.bytes_per_pixel() else {
        let img = image::load_from_memory_with_format(data, image::ImageFormat::Jpeg)
            .map_err(|e| anyhow!("an MJPG frame is not a JPEG: {e}"))?;
        if (img.width(), img.height()) != (width, height) {
            bail!(
                "an MJPG frame is {}x{} pixels, the camera said {width}x{height}",
                img.width(),
                img.height()
            );
        }
        return Ok(img.to_luma8());
    };
    let stride = if stride == 0 { w * bpp } else { stride };
    if stride < w * bpp {
        bail!("a {width}-pixel {format:?} row needs {} bytes, the stride is {stride}", w * bpp);
    }
    let need = stride * (h - 1) + w * bpp;
    if data.len() < need {
        bail!(
            "a {width}x{height} {format:?} frame needs {need} bytes, the camera gave {}",
            data.len()
        );
    }
    let rows = (0..h).map(|y| &data[y * stride..y * stride + w * bpp]);
    let grey: Vec<u8> = match format {
        PixelFormat::Grey => rows.flatten().copied().collect(),
        PixelFormat::Yuyv => rows.flat_map(|r| r.iter().step_by(2).copied()).collect(),
        PixelFormat::Uyvy => rows.flat_map(|r| r.iter().skip(1).step_by(2).copied()).collect(),
        PixelFormat::Rgb | PixelFormat::Bgr => {
            let mut rgb: Vec<u8> = rows.flatten().copied().collect();
            if format == PixelFormat::Bgr {
                rgb.chunks_exact_mut(3).for_each(|p| p.swap(0, 2));
            }
            let img = image::RgbImage::from_raw(width, height, rgb)
                .ok_or_else(|| anyhow!("a {width}x{height} RGB frame does not fit"))?;
            return Ok(image::DynamicImage::ImageRgb8(img).to_luma8());
        }
        PixelFormat::Mjpeg => unreachable!("handled above"),
    };
    GrayImage::from_raw(width, height, grey)
        .ok_or_else(|| anyhow!("a {width}x{height} frame does not fit"))
}

/// The size real cameras are opened at when none is given and the model records none.
pub const DEFAULT_SIZE: (u32, u32) = (640, 480);

/// The size to open real cameras at: the one asked for (`--camera-size`), else the size of the
/// images `blob` was trained on (its pixels mean something only there), else [`DEFAULT_SIZE`]
/// (`hvs track`, `hvs view`, and `hvs collect` without a model).
pub fn size_for(
    asked: Option<(u32, u32)>,
    blob: Option<&hvs_shared::runtime::blob::ModelBlob>,
) -> (u32, u32) {
    asked
        .or_else(|| blob.and_then(|b| b.image_size()).map(|(w, h)| (w.into(), h.into())))
        .unwrap_or(DEFAULT_SIZE)
}

/// The two cameras of `spec` as a frame source, each opened at `size` (the model's image
/// size). Without the `v4l` feature: an error saying how to build one with it.
pub fn open(spec: &CameraSpec, size: (u32, u32)) -> Result<Box<dyn FrameSource + Send>> {
    #[cfg(feature = "v4l")]
    {
        Ok(Box::new(v4l::V4lCameras::open(spec, size)?))
    }
    #[cfg(not(feature = "v4l"))]
    {
        let _ = (spec, size);
        bail!(NO_V4L)
    }
}

/// What a build without the `v4l` feature says when asked for cameras.
pub const NO_V4L: &str = "--cameras: this hvs was built without V4L2 cameras; build it with \
     `cargo install --locked --path host --features v4l` (needs libclang, Debian's libclang-dev)";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_take_paths_and_numbers_and_refuse_the_rest() {
        let s = CameraSpec::parse("v4l:0,/dev/video2").unwrap();
        assert_eq!(s.left, PathBuf::from("/dev/video0"));
        assert_eq!(s.right, PathBuf::from("/dev/video2"));
        for bad in ["0,2", "v4l:0", "v4l:0,2,4", "v4l:,2", "v4l:1,/dev/video1", "usb:0,1"] {
            let e = CameraSpec::parse(bad).unwrap_err().to_string();
            assert!(e.starts_with("--cameras:"), "{bad}: {e}");
        }
    }

    #[test]
    fn fourccs_round_trip() {
        for f in PixelFormat::PREFERRED {
            assert_eq!(PixelFormat::from_fourcc(f.fourcc()), Some(f));
        }
        assert_eq!(PixelFormat::from_fourcc(*b"NV12"), None);
    }

    #[test]
    fn packed_formats_give_their_luma() {
        // 2x2: grey levels 10 20 / 30 40.
        let want = [10u8, 20, 30, 40];
        let grey = grey_frame(PixelFormat::Grey, 2, 2, 0, &want).unwrap();
        assert_eq!(grey.as_raw(), &want);
        // YUYV with a padded stride (6 bytes a row, 4 used).
        let yuyv = [10, 128, 20, 128, 0xEE, 0xEE, 30, 99, 40, 77];
        let g = grey_frame(PixelFormat::Yuyv, 2, 2, 6, &yuyv).unwrap();
        assert_eq!(g.as_raw(), &want);
        let uyvy = [128, 10, 128, 20, 99, 30, 77, 40];
        assert_eq!(grey_frame(PixelFormat::Uyvy, 2, 2, 0, &uyvy).unwrap().as_raw(), &want);
        // RGB and BGR of the same colours give the same grey, that of `image`.
        let rgb = [200u8, 10, 10, 10, 200, 10, 10, 10, 200, 90, 90, 90];
        let bgr: Vec<u8> = rgb.chunks(3).flat_map(|p| [p[2], p[1], p[0]]).collect();
        let a = grey_frame(PixelFormat::Rgb, 2, 2, 0, &rgb).unwrap();
        let b = grey_frame(PixelFormat::Bgr, 2, 2, 0, &bgr).unwrap();
        assert_eq!(a, b);
        let img = image::RgbImage::from_raw(2, 2, rgb.to_vec()).unwrap();
        assert_eq!(a, image::DynamicImage::ImageRgb8(img).to_luma8());
        assert_eq!(a.as_raw()[3], 90);
    }

    #[test]
    fn short_or_odd_frames_are_errors() {
        let e = grey_frame(PixelFormat::Yuyv, 4, 2, 0, &[0; 15]).unwrap_err().to_string();
        assert!(e.contains("needs 16 bytes, the camera gave 15"), "{e}");
        let e = grey_frame(PixelFormat::Rgb, 4, 2, 6, &[0; 100]).unwrap_err().to_string();
        assert!(e.contains("the stride is 6"), "{e}");
        let e = grey_frame(PixelFormat::Grey, 0, 2, 0, &[]).unwrap_err().to_string();
        assert!(e.contains("empty"), "{e}");
        let e = grey_frame(PixelFormat::Mjpeg, 4, 2, 0, b"not a jpeg").unwrap_err().to_string();
        assert!(e.contains("not a JPEG"), "{e}");
    }

    #[test]
    fn mjpeg_frames_are_decoded_and_their_size_checked() {
        let img = GrayImage::from_fn(16, 8, |x, y| image::Luma([(x * 16 + y) as u8]));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 100)
            .encode_image(&img)
            .unwrap();
        let g = grey_frame(PixelFormat::Mjpeg, 16, 8, 0, &jpeg).unwrap();
        let worst = g.as_raw().iter().zip(img.as_raw()).map(|(a, b)| a.abs_diff(*b)).max();
        assert!(worst.unwrap() <= 3, "{worst:?}");
        let e = grey_frame(PixelFormat::Mjpeg, 8, 8, 0, &jpeg).unwrap_err().to_string();
        assert!(e.contains("is 16x8 pixels, the camera said 8x8"), "{e}");
    }

    #[cfg(not(feature = "v4l"))]
    #[test]
    fn a_build_without_v4l_says_how_to_get_it() {
        let spec = CameraSpec::parse("v4l:0,1").unwrap();
        let e = open(&spec, (640, 480)).err().unwrap().to_string();
        assert_eq!(e, NO_V4L);
    }

    #[cfg(feature = "v4l")]
    #[test]
    fn a_missing_device_is_named() {
        let spec =
            CameraSpec::parse("v4l:/nonexistent/video-left,/nonexistent/video-right").unwrap();
        let e = format!("{:#}", open(&spec, (640, 480)).err().unwrap());
        assert!(e.contains("/nonexistent/video-left"), "{e}");
    }
}
