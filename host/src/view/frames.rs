//! What `hvs view` shows: a [`PairStore`] holds each pair's left and right frame (and the
//! detected corners drawn on them) as PNG bytes with a sequence number, and the grey images
//! the matcher reads. [`StillFrames`] is the still one (a pair of files, a capture set). Frames
//! are *grabbed* through the one camera interface, [`crate::track::frames::FrameSource`] (the
//! virtual cameras today): a live store fed from such a source keeps the latest pair and bumps
//! the sequence number, and the page, which polls, shows each new frame.

use crate::vision::png_bytes_fast;
use hvs_vision::detect::StereoCorners;
use image::GrayImage;
use std::sync::{Arc, OnceLock};

/// Which picture of a pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum View {
    /// The left camera's frame.
    Left,
    /// The right camera's frame.
    Right,
    /// The left frame with the detected corners and their labels.
    LeftCorners,
    /// The right frame with the detected corners and their labels.
    RightCorners,
}

impl View {
    /// The view named in a URL: `left`, `right`, `left-corners`, `right-corners`.
    pub fn parse(s: &str) -> Option<View> {
        Some(match s {
            "left" => View::Left,
            "right" => View::Right,
            "left-corners" => View::LeftCorners,
            "right-corners" => View::RightCorners,
            _ => return None,
        })
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// One encoded frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Counts the frames of a live source (0 for a still one).
    pub seq: u64,
    /// The PNG bytes.
    pub png: Arc<Vec<u8>>,
}

/// A left and a right grey image.
pub type GreyPair = (Arc<GrayImage>, Arc<GrayImage>);

/// What the server shows and matches on.
pub trait PairStore: Send + Sync {
    /// How many pairs there are.
    fn len(&self) -> usize;
    /// Whether there are none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether frames change (the page keeps polling) or stay (the page loads them once).
    fn live(&self) -> bool;
    /// The latest frame of `view` of pair `pair`, `None` if there is none (an unreadable
    /// image, corners of a pair where none were found).
    fn frame(&self, pair: usize, view: View) -> Option<Frame>;
    /// The frame of `view` of pair `pair` grabbed as number `seq`, `None` when the store does
    /// not keep it ([`Self::kept_seqs`]: a live store keeps the last few, so that a page that
    /// got the left frame of `seq` can ask for the right one of the same pair) or has none
    /// of that view. Never another frame: its image would pair with one of another time.
    fn frame_at(&self, pair: usize, view: View, seq: u64) -> Option<Frame> {
        self.frame(pair, view).filter(|f| f.seq == seq)
    }
    /// The numbers of the oldest and the newest frame kept, `None` before the first (a still
    /// store keeps its one frame, number 0).
    fn kept_seqs(&self) -> Option<(u64, u64)> {
        Some((0, 0))
    }
    /// The sequence number of the latest frame (0 for a still store, which never changes).
    fn latest_seq(&self) -> u64 {
        0
    }
    /// The latest grey images of pair `pair`, for the matcher.
    fn grey(&self, pair: usize) -> Option<GreyPair>;
}

/// A still pair: its images and, where detected, its corners.
pub struct StillPair {
    grey: Option<GreyPair>,
    corners: Option<Box<StereoCorners>>,
    png: [OnceLock<Option<Arc<Vec<u8>>>>; 4],
}

impl StillPair {
    /// A pair of images (`None`: unreadable) with its detected corners, if any.
    pub fn new(grey: Option<[GrayImage; 2]>, corners: Option<Box<StereoCorners>>) -> StillPair {
        StillPair {
            grey: grey.map(|[l, r]| (Arc::new(l), Arc::new(r))),
            corners,
            png: Default::default(),
        }
    }

    fn encode(&self, view: View) -> Option<Vec<u8>> {
        let (l, r) = self.grey.as_ref()?;
        let corners = || self.corners.as_ref();
        match view {
            View::Left => png_bytes_fast(&**l).ok(),
            View::Right => png_bytes_fast(&**r).ok(),
            View::LeftCorners => {
                png_bytes_fast(&hvs_vision::overlay::draw_corners(l, &corners()?.left)).ok()
            }
            View::RightCorners => {
                png_bytes_fast(&hvs_vision::overlay::draw_corners(r, &corners()?.right)).ok()
            }
        }
    }
}

/// Frames that do not change: encoded once, when first asked for.
pub struct StillFrames {
    pairs: Vec<StillPair>,
}

impl StillFrames {
    /// The pairs, in order.
    pub fn new(pairs: Vec<StillPair>) -> StillFrames {
        StillFrames { pairs }
    }
}

impl PairStore for StillFrames {
    fn len(&self) -> usize {
        self.pairs.len()
    }

    fn live(&self) -> bool {
        false
    }

    fn frame(&self, pair: usize, view: View) -> Option<Frame> {
        let p = self.pairs.get(pair)?;
        let png = p.png[view.index()].get_or_init(|| p.encode(view).map(Arc::new)).clone()?;
        Some(Frame { seq: 0, png })
    }

    fn grey(&self, pair: usize) -> Option<GreyPair> {
        self.pairs.get(pair)?.grey.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn still_frames_are_the_images_and_nothing_else() {
        let l = GrayImage::from_fn(8, 6, |x, y| image::Luma([(x * 20 + y) as u8]));
        let r = GrayImage::from_pixel(8, 6, image::Luma([7]));
        let f = StillFrames::new(vec![
            StillPair::new(Some([l.clone(), r.clone()]), None),
            StillPair::new(None, None),
        ]);
        assert_eq!((f.len(), f.live()), (2, false));
        let png = f.frame(0, View::Left).unwrap();
        assert_eq!(image::load_from_memory(&png.png).unwrap().to_luma8(), l);
        let png = f.frame(0, View::Right).unwrap();
        assert_eq!(image::load_from_memory(&png.png).unwrap().to_luma8(), r);
        // No corners detected, an unreadable pair, no such pair, no such view.
        assert!(f.frame(0, View::LeftCorners).is_none());
        assert!(f.frame(1, View::Left).is_none() && f.grey(1).is_none());
        assert!(f.frame(2, View::Left).is_none());
        // Its one frame is number 0: no other number gives it.
        assert_eq!(f.kept_seqs(), Some((0, 0)));
        assert_eq!(f.frame_at(0, View::Right, 0).unwrap().png, png.png);
        assert!(f.frame_at(0, View::Right, 1).is_none());
        assert_eq!(View::parse("right-corners"), Some(View::RightCorners));
        for bad in ["", "LEFT", "../left", "left/"] {
            assert_eq!(View::parse(bad), None, "{bad}");
        }
    }
}
