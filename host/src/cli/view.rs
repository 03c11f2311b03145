//! `hvs view`: a local page that shows what the head sees ([`crate::view`]): a still pair
//! (click a pixel: `hvs locate --at`), a capture set (detected corners, residuals, untick
//! pairs and retrain) or the virtual head in a scene, live (look at a clicked pixel, the
//! nearest object, home), and the model.

use crate::view::{serve, RetrainOptions, Session, Source};
use anyhow::{bail, Result};
use std::net::SocketAddr;
use std::path::PathBuf;

/// Arguments of `hvs view`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Serve a local page showing a stereo pair or a capture set and the model",
    long_about = "Serve a local page (HTML, JavaScript and CSS inside the binary) that shows a \
    stereo pair (--left/--right: click a left pixel to see its match, X, Y, Z, status and \
    score, the numbers of `hvs locate --at`; tick \"depth\" for the pair's dense depth, `hvs \
    depth --thorough --colour`) or a capture set (--board/--captures: every pair \
    with its detected corners, homography and epipolar residuals; untick pairs and retrain as \
    `hvs train` does) or the virtual head in a scene, live (--scene: both frames as they are \
    grabbed; click a pixel and \"look\" to make the head look at the object there and follow \
    it, as `hvs track --target U,V` does; the joints and the loop's status update live), or two \
    real cameras, live (--cameras v4l:A,B, on no head: click a pixel for its X, Y, Z; needs a \
    build with the v4l feature), and the model (what `hvs info` prints). It listens on 127.0.0.1 unless \
    --listen names another address, and then every request needs the token in the printed URL. \
    Ctrl-C stops it.",
    group(clap::ArgGroup::new("source").required(true).args(["left", "board", "scene", "cameras"]))
)]
pub struct Args {
    /// The model (from `hvs train`).
    #[arg(long, value_name = "M.hvsw")]
    pub model: PathBuf,
    /// The left image of a still pair (PNG or JPEG).
    #[arg(long, value_name = "L.png", requires = "right")]
    pub left: Option<PathBuf>,
    /// The right image, the same size.
    #[arg(long, value_name = "R.png", requires = "left")]
    pub right: Option<PathBuf>,
    /// The board of a capture set (as `hvs board detect`).
    #[arg(long, value_name = "BOARD.json", requires = "captures", conflicts_with = "left")]
    pub board: Option<PathBuf>,
    /// The capture set (as `hvs board detect`).
    #[arg(long, value_name = "CAPTURES.csv", requires = "board")]
    pub captures: Option<PathBuf>,
    /// A scene for the virtual head (as `hvs track`): the head in the loop, live.
    #[arg(long, value_name = "SCENE.json", conflicts_with_all = ["left", "board"])]
    pub scene: Option<PathBuf>,
    /// Two real cameras, live: v4l:LEFT,RIGHT (device paths or numbers, e.g. v4l:0,2; a build
    /// with the `v4l` feature). They stand on no head: the model is used at the home posture.
    #[arg(long, value_name = "v4l:A,B", conflicts_with_all = ["left", "board", "scene"])]
    pub cameras: Option<String>,
    /// With --cameras: the image size to ask of them (default: the model's training images'
    /// size when it records one, else 640x480).
    #[arg(long, value_name = "WxH", requires = "cameras")]
    pub camera_size: Option<String>,
    /// With --cameras: the head they stand on, a head controller on a link (a serial port
    /// `/dev/ttyUSB0`, `serial:PATH[@BAUD]`, or `tcp:HOST:PORT`), moved with posture commands
    /// (protocol 3): "look" then turns it.
    #[arg(long, value_name = "PATH", requires = "cameras")]
    pub port: Option<String>,
    /// With --scene, the head: `emulate` (the head's logic on the host) or `qemu` (the head
    /// firmware in QEMU, moved with posture commands).
    #[arg(long, value_enum, default_value = "emulate", requires = "scene")]
    pub head: super::HeadKind,
    /// With --head qemu: the firmware ELF [default: as `hvs emulate`].
    #[arg(long, value_name = "ELF", requires = "scene")]
    pub firmware: Option<PathBuf>,
    /// Address to listen on; port 0 picks a free one (the URL printed says which).
    #[arg(long, value_name = "ADDR:PORT", default_value = "127.0.0.1:8080")]
    pub listen: String,
    /// Restarts of a retrain (`hvs train --restarts`) [default: `hvs train`'s for the set].
    #[arg(long, value_name = "R", allow_negative_numbers = true, value_parser = crate::cli::whole_usize)]
    pub restarts: Option<usize>,
    /// Seed of a retrain (`hvs train --seed`) and of the virtual cameras' sensor noise.
    #[arg(long, value_name = "S", default_value_t = 0, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    pub seed: u64,
}

/// `hvs view`.
pub fn run(a: Args) -> Result<()> {
    // An address, or `localhost:PORT` (the name every system has; others would need a
    // lookup whose answer could be any interface).
    let listen: SocketAddr = a
        .listen
        .strip_prefix("localhost:")
        .map_or_else(|| a.listen.clone(), |port| format!("127.0.0.1:{port}"))
        .parse()
        .map_err(|_| {
            crate::cli::usage(format!(
                "--listen: {:?} is not ADDR:PORT (e.g. 127.0.0.1:8080, localhost:8080, 0.0.0.0:0, [::1]:8080)",
                a.listen
            ))
        })?;
    // A retrain's restarts, checked at the start (not at the first retrain).
    a.restarts.map(crate::cli::check_restarts).transpose()?;
    let source = match (a.left, a.right, a.board, a.captures, a.scene, a.cameras) {
        (Some(left), Some(right), None, None, None, None) => Source::Pair { left, right },
        (None, None, Some(board), Some(captures), None, None) => {
            Source::Captures { board, captures }
        }
        (None, None, None, None, Some(scene), None) => {
            Source::Scene { scene, seed: a.seed, head: a.head.choice(a.firmware) }
        }
        (None, None, None, None, None, Some(cameras)) => Source::Cameras {
            spec: crate::track::cameras::CameraSpec::parse(&cameras)
                .map_err(|e| crate::cli::usage(e.to_string()))?,
            size: a.camera_size.as_deref().map(crate::cli::parse_camera_size).transpose()?,
            port: a.port.as_deref().map(crate::cli::port_arg).transpose()?,
        },
        _ => bail!(
            "give --left L --right R, --board BOARD.json --captures CAPTURES.csv, --scene \
             SCENE.json or --cameras v4l:A,B"
        ),
    };
    let options = RetrainOptions { restarts: a.restarts, seed: a.seed };
    let session = Session::open(&a.model, &source, options)?;
    if matches!(source, Source::Scene { .. } | Source::Cameras { .. }) {
        // The live head turns its eyes: say so of a model for one posture.
        if let Some(w) = crate::track::fixed_posture_warning(&session.model.blob) {
            eprintln!("warning: {}: {w}", a.model.display());
        }
    }
    serve(session, listen, |url| crate::cli::say(format_args!("hvs view: serving {url}")))
}

#[cfg(test)]
mod tests {
    #[test]
    fn camera_sizes_are_parsed_and_checked() {
        assert_eq!(crate::cli::parse_camera_size("640x480").unwrap(), (640, 480));
        assert_eq!(crate::cli::parse_camera_size("1280X720").unwrap(), (1280, 720));
        for bad in ["640", "640x", "x480", "-640x480", "8x8", "640x480x3", "99999x10"] {
            let e = crate::cli::parse_camera_size(bad).unwrap_err().to_string();
            assert!(e.starts_with("--camera-size"), "{bad}: {e}");
        }
    }
}
