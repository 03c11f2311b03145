//! Two V4L2 cameras (the `v4l` crate, memory-mapped streaming) as a [`FrameSource`].

use super::{grey_frame, CameraSpec, PixelFormat};
use crate::track::frames::{Frame, FrameSource};
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use image::GrayImage;
use std::path::PathBuf;
use std::time::Duration;
use v4l::buffer::Type;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream;
use v4l::video::Capture;
use v4l::{Device, FourCC};

/// How long a grab waits for a camera's frame before it says the camera stopped.
const GRAB_TIMEOUT: Duration = Duration::from_secs(2);
/// Buffers per stream: two, so that a frame is at most one frame old when it is read.
const BUFFERS: u32 = 2;

/// One opened camera.
struct Eye {
    path: PathBuf,
    format: PixelFormat,
    stride: usize,
    size: (u32, u32),
    stream: Stream<'static>,
    // The stream uses the device's handle; the device is kept open beside it.
    _device: Device,
}

impl Eye {
    fn open(path: PathBuf, (width, height): (u32, u32)) -> Result<Eye> {
        let device = Device::with_path(&path).with_context(|| format!("{}", path.display()))?;
        let offered = device.enum_formats().with_context(|| format!("{}", path.display()))?;
        let format = PixelFormat::PREFERRED
            .into_iter()
            .find(|f| offered.iter().any(|o| o.fourcc == FourCC::new(&f.fourcc())))
            .ok_or_else(|| {
                let names: Vec<String> = offered.iter().map(|o| o.fourcc.to_string()).collect();
                anyhow!(
                    "{}: offers none of GREY, YUYV, UYVY, MJPG, RGB3, BGR3 (it offers {})",
                    path.display(),
                    names.join(", ")
                )
            })?;
        let mut want = device.format().with_context(|| format!("{}", path.display()))?;
        want.width = width;
        want.height = height;
        want.fourcc = FourCC::new(&format.fourcc());
        let got = device.set_format(&want).with_context(|| format!("{}", path.display()))?;
        if (got.width, got.height) != (width, height) {
            bail!(
                "{}: the camera gives {}x{} pixels, the model's images are {width}x{height}",
                path.display(),
                got.width,
                got.height
            );
        }
        let format = PixelFormat::from_fourcc(got.fourcc.repr).ok_or_else(|| {
            anyhow!("{}: the camera switched to the format {}", path.display(), got.fourcc)
        })?;
        let mut stream = Stream::with_buffers(&device, Type::VideoCapture, BUFFERS)
            .with_context(|| format!("{}: starting the stream", path.display()))?;
        stream.set_timeout(GRAB_TIMEOUT);
        Ok(Eye {
            path,
            format,
            stride: got.stride as usize,
            size: (width, height),
            stream,
            _device: device,
        })
    }

    fn grab(&mut self) -> Result<GrayImage> {
        let (data, meta) = self.stream.next().map_err(|e| {
            if e.kind() == std::io::ErrorKind::TimedOut {
                anyhow!("{}: no frame within {} s", self.path.display(), GRAB_TIMEOUT.as_secs())
            } else {
                anyhow!("{}: {e}", self.path.display())
            }
        })?;
        let used = (meta.bytesused as usize).min(data.len());
        let data = if used > 0 { &data[..used] } else { data };
        grey_frame(self.format, self.size.0, self.size.1, self.stride, data)
            .with_context(|| format!("{}", self.path.display()))
    }
}

/// Two V4L2 cameras, each grabbed in turn.
pub struct V4lCameras {
    left: Eye,
    right: Eye,
}

impl V4lCameras {
    /// Opens both cameras of `spec` at `size`: the first format of
    /// [`PixelFormat::PREFERRED`] each offers, two memory-mapped buffers.
    pub fn open(spec: &CameraSpec, size: (u32, u32)) -> Result<V4lCameras> {
        let left = Eye::open(spec.left.clone(), size).context("left camera")?;
        let right = Eye::open(spec.right.clone(), size).context("right camera")?;
        Ok(V4lCameras { left, right })
    }
}

impl FrameSource for V4lCameras {
    fn grab(&mut self, _t_s: f64, _joints: &Joints) -> Result<Frame> {
        let left = self.left.grab().context("left camera")?;
        let right = self.right.grab().context("right camera")?;
        Ok(Frame { left, right, truth: None })
    }
}
