//! Image files in: which formats are read and how large an image may be, the same for every
//! command that reads an image (`hvs board detect`, `hvs locate`, `hvs head look`,
//! `hvs demo --images`).
//!
//! - **Formats**: PNG and JPEG, told by the file's first bytes (not by its name). Other formats
//!   the decoder happens to know (BMP, TIFF, WebP, GIF, ...) are refused, naming the format.
//! - **Size**: at most [`MAX_PIXELS`] pixels (width x height), read from the header and
//!   refused before anything is decoded, so a small file claiming a huge image (a
//!   "decompression bomb") costs nothing. The decoder's own allocations are capped too.
//!
//! [`crate::render`] refuses to render images above the same limit, so that everything it
//! writes can be read back.

use image::{GrayImage, ImageFormat, ImageReader};
use std::path::Path;

/// The most pixels (width x height) an image may have: 16 million (e.g. 4,896 x 3,264, a
/// 16-megapixel camera). Above it a pair of images, decoded, detected or matched, would no
/// longer fit the 1 GB and 10 s every command keeps to; scale larger photos down first.
pub const MAX_PIXELS: u64 = 16_000_000;

/// The largest single allocation the decoder may make: the limit at 16-bit RGBA.
const MAX_ALLOC: u64 = MAX_PIXELS * 8 + (1 << 20);

/// Why an image file was not read. Its `Display` is one line naming the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ImageFileError {
    /// The file could not be opened or read (path, OS message).
    Io(String, String),
    /// The file is not PNG or JPEG (path, what it looks like, if known).
    Format(String, Option<String>),
    /// The header gives more than [`MAX_PIXELS`] pixels (path, width, height).
    TooLarge(String, u32, u32),
    /// The header gives an empty image (path, width, height).
    Empty(String, u32, u32),
    /// The image data are damaged or truncated (path, decoder message).
    Decode(String, String),
    /// A 16-bit image whose levels all lie below 256 (path, the largest level): 8-bit values
    /// stored in 16 bits, black once read as 8 bits.
    LowSixteen(String, u16),
}

impl core::fmt::Display for ImageFileError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ImageFileError::Io(p, e) => write!(f, "{p}: cannot read: {e}"),
            ImageFileError::Format(p, Some(k)) => write!(
                f,
                "{p}: a {k} file; hvs reads PNG and JPEG images only (convert it first)"
            ),
            ImageFileError::Format(p, None) => write!(
                f,
                "{p}: not a PNG or JPEG image (hvs reads PNG and JPEG images only)"
            ),
            ImageFileError::TooLarge(p, w, h) => write!(
                f,
                "{p}: {w}x{h} is {} pixels, more than the {MAX_PIXELS} an image may have (scale it down)",
                u64::from(*w) * u64::from(*h)
            ),
            ImageFileError::Empty(p, w, h) => write!(f, "{p}: the image is {w}x{h}: empty"),
            ImageFileError::Decode(p, e) => {
                write!(f, "{p}: damaged or truncated image data ({e})")
            }
            ImageFileError::LowSixteen(p, max) => write!(
                f,
                "{p}: a 16-bit image whose levels all lie at or below {max} of 65535: 8-bit values stored in 16 bits? Read as 8 bits it is black; save it with 8 bits per channel (or its full 16-bit range)"
            ),
        }
    }
}

impl std::error::Error for ImageFileError {}

/// The name of a format for a message.
fn format_name(f: ImageFormat) -> String {
    f.extensions_str().first().map_or_else(|| format!("{f:?}"), |e| e.to_uppercase())
}

/// A decoder message fit for one line: the decoder's text when it is prose, a plain
/// description when it carries Rust debug output (braces, paths).
fn plain(e: &image::ImageError) -> String {
    let text = e.to_string();
    let debug_like = text.contains(['{', '}']) || text.contains("::") || text.contains('\n');
    if debug_like {
        match e {
            image::ImageError::Limits(_) => "the decoder would need too much memory".into(),
            image::ImageError::Unsupported(_) => "an unsupported variant of the format".into(),
            _ => "the decoder could not read it".into(),
        }
    } else {
        text
    }
}

fn reader(
    path: &Path,
    shown: &str,
) -> Result<ImageReader<std::io::BufReader<std::fs::File>>, ImageFileError> {
    let io = |e: std::io::Error| ImageFileError::Io(shown.to_string(), e.to_string());
    let meta = std::fs::metadata(path).map_err(io)?;
    if meta.is_dir() {
        return Err(ImageFileError::Io(shown.to_string(), "is a directory".into()));
    }
    // The format by the first bytes alone (`with_guessed_format` falls back on the name's
    // extension, so a text file called `x.png` would be "damaged PNG data"); peeked at in
    // the reader's buffer, nothing consumed.
    let mut file = std::io::BufReader::new(std::fs::File::open(path).map_err(io)?);
    let format = image::guess_format(std::io::BufRead::fill_buf(&mut file).map_err(io)?).ok();
    let mut r = ImageReader::new(file);
    if let Some(f) = format {
        r.set_format(f);
    }
    Ok(r)
}

/// The format and size of an image file, read from its header only, checked against the
/// formats and [`MAX_PIXELS`].
pub fn probe(path: &Path) -> Result<(ImageFormat, u32, u32), ImageFileError> {
    let shown = path.display().to_string();
    let r = reader(path, &shown)?;
    let format = match r.format() {
        Some(f @ (ImageFormat::Png | ImageFormat::Jpeg)) => f,
        Some(other) => return Err(ImageFileError::Format(shown, Some(format_name(other)))),
        None => return Err(ImageFileError::Format(shown, None)),
    };
    let (w, h) =
        r.into_dimensions().map_err(|e| ImageFileError::Decode(shown.clone(), plain(&e)))?;
    check_size(&shown, w, h)?;
    Ok((format, w, h))
}

/// Fails unless `w x h` is a non-empty image of at most [`MAX_PIXELS`] (`shown` names it).
pub fn check_size(shown: &str, w: u32, h: u32) -> Result<(), ImageFileError> {
    if w == 0 || h == 0 {
        return Err(ImageFileError::Empty(shown.to_string(), w, h));
    }
    if u64::from(w) * u64::from(h) > MAX_PIXELS {
        return Err(ImageFileError::TooLarge(shown.to_string(), w, h));
    }
    Ok(())
}

/// Reads a PNG or JPEG file (any colour type, any bit depth) as grey levels (Rec. 709 luma),
/// after [`probe`]: refused before decoding when too large or of another format.
pub fn read_grey(path: &Path) -> Result<GrayImage, ImageFileError> {
    let shown = path.display().to_string();
    let (format, w, h) = probe(path)?;
    let mut r = reader(path, &shown)?;
    r.set_format(format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    limits.max_alloc = Some(MAX_ALLOC);
    r.limits(limits);
    let img = r.decode().map_err(|e| ImageFileError::Decode(shown.clone(), plain(&e)))?;
    if let Some(max) = sixteen_bit_max(&img).filter(|m| (1..256).contains(m)) {
        return Err(ImageFileError::LowSixteen(shown, max));
    }
    Ok(img.to_luma8())
}

/// The largest channel level of a 16-bit image (alpha left out), `None` for other depths.
fn sixteen_bit_max(img: &image::DynamicImage) -> Option<u16> {
    use image::DynamicImage as D;
    let max = |v: &[u16], step: usize, colour: usize| {
        v.chunks_exact(step).flat_map(|p| p[..colour].iter().copied()).max().unwrap_or(0)
    };
    match img {
        D::ImageLuma16(i) => Some(max(i.as_raw(), 1, 1)),
        D::ImageLumaA16(i) => Some(max(i.as_raw(), 2, 1)),
        D::ImageRgb16(i) => Some(max(i.as_raw(), 3, 3)),
        D::ImageRgba16(i) => Some(max(i.as_raw(), 4, 3)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png_header(w: u32, h: u32) -> Vec<u8> {
        // Signature + an IHDR chunk (8-bit grey) with its CRC; no image data.
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend_from_slice(&w.to_be_bytes());
        ihdr.extend_from_slice(&h.to_be_bytes());
        ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
        let crc = crc32(&ihdr);
        let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
        out.extend_from_slice(&13u32.to_be_bytes());
        out.extend_from_slice(&ihdr);
        out.extend_from_slice(&crc.to_be_bytes());
        // The start of an IDAT chunk (the header ends where the data begin).
        let idat = b"IDAT\x78\x01";
        out.extend_from_slice(&2u32.to_be_bytes());
        out.extend_from_slice(idat);
        out.extend_from_slice(&crc32(idat).to_be_bytes());
        out
    }

    fn crc32(data: &[u8]) -> u32 {
        crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC).checksum(data)
    }

    #[test]
    fn eight_bit_levels_in_a_sixteen_bit_image_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let low = dir.path().join("low.png");
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(8, 8, |x, y| {
            image::Luma([(x * 30 + y) as u16])
        });
        img.save(&low).unwrap();
        let e = read_grey(&low).unwrap_err().to_string();
        assert!(e.contains("low.png: a 16-bit image") && e.contains("at or below 217"), "{e}");
        // The full 16-bit range is read (and so is an all-black one, which is simply black).
        let full = dir.path().join("full.png");
        image::ImageBuffer::<image::Luma<u16>, _>::from_fn(8, 8, |x, _| {
            image::Luma([x as u16 * 9000])
        })
        .save(&full)
        .unwrap();
        assert_eq!(read_grey(&full).unwrap()[(7, 0)][0], (63000.0f64 / 257.0).round() as u8);
        let black = dir.path().join("black.png");
        image::ImageBuffer::<image::Luma<u16>, _>::new(8, 8).save(&black).unwrap();
        assert_eq!(read_grey(&black).unwrap()[(0, 0)][0], 0);
    }

    #[test]
    fn formats_and_sizes_are_checked_before_decoding() {
        let dir = tempfile::tempdir().unwrap();
        let ok = dir.path().join("ok.png");
        GrayImage::from_pixel(40, 30, image::Luma([7])).save(&ok).unwrap();
        let g = read_grey(&ok).unwrap();
        assert_eq!((g.width(), g.height(), g[(3, 4)][0]), (40, 30, 7));

        let bomb = dir.path().join("bomb.png");
        std::fs::write(&bomb, png_header(20_000, 20_000)).unwrap();
        let e = read_grey(&bomb).unwrap_err();
        assert!(matches!(e, ImageFileError::TooLarge(_, 20_000, 20_000)), "{e}");
        assert!(e.to_string().contains("20000x20000"), "{e}");
        // At the limit the header passes (the data are missing: a decode error, not a size one).
        let edge = dir.path().join("edge.png");
        std::fs::write(&edge, png_header(4000, 4000)).unwrap();
        assert!(matches!(read_grey(&edge), Err(ImageFileError::Decode(..))));

        let bmp = dir.path().join("x.png");
        std::fs::write(&bmp, b"BM\x3a\0\0\0\0\0\0\0\x36\0\0\0\x28\0\0\0").unwrap();
        let e = read_grey(&bmp).unwrap_err().to_string();
        assert!(e.contains("a BMP file") && e.contains("PNG and JPEG"), "{e}");
        let text = dir.path().join("t.txt");
        std::fs::write(&text, "not an image").unwrap();
        assert!(matches!(read_grey(&text), Err(ImageFileError::Format(_, None))));
        // Named as a PNG, not one: not "damaged PNG data".
        let named = dir.path().join("text.png");
        std::fs::write(&named, "not an image either").unwrap();
        let e = read_grey(&named).unwrap_err();
        assert!(matches!(e, ImageFileError::Format(_, None)), "{e}");
        assert!(e.to_string().contains("not a PNG or JPEG image"), "{e}");
        std::fs::write(&named, "").unwrap();
        assert!(matches!(read_grey(&named), Err(ImageFileError::Format(_, None))));
        let e = read_grey(&dir.path().join("missing.png")).unwrap_err();
        assert!(matches!(e, ImageFileError::Io(..)), "{e}");
        assert!(matches!(read_grey(dir.path()), Err(ImageFileError::Io(..))));

        // A damaged chunk: one line, no Rust debug output.
        let mut bytes = std::fs::read(&ok).unwrap();
        let n = bytes.len();
        bytes[n - 20] ^= 0xFF;
        bytes.truncate(n - 8);
        let broken = dir.path().join("broken.png");
        std::fs::write(&broken, &bytes).unwrap();
        let e = read_grey(&broken).unwrap_err().to_string();
        assert!(!e.contains('{') && !e.contains('\n'), "{e}");
        assert!(e.starts_with(&broken.display().to_string()), "{e}");
    }
}
