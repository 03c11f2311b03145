//! The head-controller wire protocol: `postcard` messages in COBS frames.
//!
//! Every frame on the wire is `COBS(postcard(message)) 0x00`. The host sends a [`Request`]; the
//! head answers with a [`Response`] carrying the same `id`. Id [`UNSOLICITED_ID`] (0) is
//! reserved for messages the head sends on its own: the boot announcement
//! ([`ResponseBody::Ready`]) and errors about frames whose id could not be read. Hosts number
//! their requests from 1.
//!
//! Encoding and decoding work over caller buffers (no allocation); [`FrameAccumulator`] turns a
//! byte stream into frames, dropping frames longer than its buffer until the next `0x00`. Both
//! the firmware and the host CLI use this module, so the two can never disagree on the format.
//!
//! Floats travel as their IEEE-754 bits (postcard writes `f32` as 4 little-endian bytes), so an
//! estimate computed on the head arrives bit for bit.

use crate::runtime::blob::BlobError;
pub use crate::runtime::gaze::Joints;
pub use crate::runtime::layout::Slot;
pub use crate::runtime::traditional::Calibration;
use serde::{Deserialize, Serialize};

/// Version of this protocol, reported by [`ResponseBody::Ready`] and [`InfoData`]. Bumped on
/// every incompatible change of the message types (2: [`InfoData::stack_peak`]; 3:
/// [`RequestBody::Posture`] and [`RequestBody::State`], answered by [`ResponseBody::State`]).
pub const PROTOCOL_VERSION: u16 = 3;

/// Request id reserved for messages the head sends without being asked.
pub const UNSOLICITED_ID: u32 = 0;

/// Longest frame on the wire, sentinel `0x00` included. Every message of this module encodes
/// to at most this many bytes (tested for the largest ones), so a receive buffer of this size
/// never drops a well-formed frame.
pub const MAX_FRAME_LEN: usize = 160;

/// Default serial speed of the protocol USART (8N1).
pub const BAUD_RATE: u32 = 115_200;

/// A matched point pair in pixels: `(u_l, v_l)` in the left image, `(u_r, v_r)` in the right.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StereoPoint {
    /// Left image column (px).
    pub u_l: f32,
    /// Left image row (px).
    pub v_l: f32,
    /// Right image column (px).
    pub u_r: f32,
    /// Right image row (px).
    pub v_r: f32,
}

impl StereoPoint {
    /// The point as the network input vector `[u_l, v_l, u_r, v_r]`.
    pub fn to_array(self) -> [f32; 4] {
        [self.u_l, self.v_l, self.u_r, self.v_r]
    }

    /// True when all four coordinates are finite (neither NaN nor infinite).
    pub fn is_finite(self) -> bool {
        self.to_array().iter().all(|c| c.is_finite())
    }
}

/// A request from the host, answered by a [`Response`] with the same `id`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Request {
    /// Chosen by the host (non-zero), echoed in the response.
    pub id: u32,
    /// What is asked.
    pub body: RequestBody,
}

/// The requests the head understands.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum RequestBody {
    /// Liveness check, answered by [`ResponseBody::Pong`].
    Ping,
    /// Firmware, slot and model description, answered by [`ResponseBody::Info`].
    Info,
    /// Depth estimate of a matched point pair, answered by [`ResponseBody::Estimate`].
    Estimate(StereoPoint),
    /// Estimate, then move the head to fixate the estimate; answered by [`ResponseBody::Look`].
    Look(StereoPoint),
    /// Move all axes to their home positions; answered by [`ResponseBody::Home`].
    Home,
    /// Run `count` inferences on `point` and report the elapsed SysTick ticks; answered by
    /// [`ResponseBody::Bench`]. Only firmware built with its `bench` feature runs it, others
    /// answer [`ErrorCode::Unsupported`].
    Bench {
        /// The input of every inference.
        point: StereoPoint,
        /// Number of inferences (the head caps it, see [`BenchData::count`]).
        count: u32,
    },
    /// Move the head to these joint angles (degrees, [`Axis`](crate::runtime::gaze::Axis)
    /// order): each clamped to its limits, on the 0.18 degree grid, along the gaze
    /// controller's trajectories, as `Look` moves. What a loop on the host sends once it has
    /// decided where to look (`hvs track --head qemu`, a real head). A NaN joint keeps its
    /// current goal; an infinite one is refused ([`ErrorCode::NonFinite`]) and nothing moves.
    /// Answered by [`ResponseBody::State`] after the move has started.
    Posture(Joints),
    /// Where the head is now; answered by [`ResponseBody::State`].
    State,
}

/// A response of the head.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Response {
    /// The id of the request answered, or [`UNSOLICITED_ID`].
    pub id: u32,
    /// The answer.
    pub body: ResponseBody,
}

/// The answers of the head.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum ResponseBody {
    /// Sent once with [`UNSOLICITED_ID`] when the head has booted and listens.
    Ready {
        /// The head's [`PROTOCOL_VERSION`].
        protocol: u16,
    },
    /// Answer to [`RequestBody::Ping`].
    Pong,
    /// Answer to [`RequestBody::Info`].
    Info(InfoData),
    /// Answer to [`RequestBody::Estimate`].
    Estimate(EstimateData),
    /// Answer to [`RequestBody::Look`].
    Look(LookData),
    /// Answer to [`RequestBody::Home`]: the home targets were accepted.
    Home,
    /// Answer to [`RequestBody::Bench`].
    Bench(BenchData),
    /// The request could not be served; nothing was changed.
    Error(ErrorCode),
    /// Answer to [`RequestBody::State`] and [`RequestBody::Posture`].
    State(StateData),
}

/// The head's posture and clock: answer to [`RequestBody::State`] and [`RequestBody::Posture`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StateData {
    /// The joints now: the gaze controller's current setpoints, the angles the servos are
    /// commanded to and posture-aware networks see (degrees, within the limits, on the grid).
    pub joints: Joints,
    /// Where the current move ends (degrees, within the limits, on the grid).
    pub goal: Joints,
    /// Control ticks since boot (wrapping): the head's clock.
    pub ticks: u32,
    /// Whether a move is under way.
    pub moving: bool,
}

/// Why a request failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorCode {
    /// The frame was not a valid COBS/postcard request (garbage, truncated, trailing bytes).
    /// Sent with [`UNSOLICITED_ID`] since the id could not be read.
    Malformed,
    /// The frame was longer than [`MAX_FRAME_LEN`] and was dropped.
    Oversize,
    /// A coordinate of the point was NaN or infinite.
    NonFinite,
    /// `Look`: the estimate cannot be fixated (behind the cameras or nearer than the minimum
    /// fixation distance); the head does not move.
    Unreachable,
    /// The point has no depth estimate (for example zero or negative disparity in fallback
    /// mode, or a network output that is not finite).
    NoSolution,
    /// This firmware does not implement the request (for example `Bench` without the `bench`
    /// feature).
    Unsupported,
}

/// Semantic version of the firmware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FirmwareVersion {
    /// Major.
    pub major: u16,
    /// Minor.
    pub minor: u16,
    /// Patch.
    pub patch: u16,
}

/// What the head found in one weight slot at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum SlotStatus {
    /// No blob: the slot does not start with the blob magic (erased or never written).
    Empty,
    /// A blob that failed validation (version, topology fields, length, CRC, parameters).
    Invalid(BlobError),
    /// A valid blob with a topology this firmware cannot run.
    UnsupportedTopology {
        /// Inputs of the blob's network.
        inputs: u16,
        /// Hidden neurons.
        hidden: u16,
        /// Outputs.
        outputs: u16,
    },
    /// A valid blob this firmware can run.
    Valid {
        /// Its generation number.
        generation: u32,
    },
}

/// How the head computes depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Mode {
    /// The network of a valid weight slot.
    Network,
    /// The traditional method with a built-in calibration (no slot could be run).
    Fallback,
}

/// Description of the network the head runs (from the blob's metadata).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ModelInfo {
    /// Inputs (4).
    pub inputs: u16,
    /// Hidden neurons.
    pub hidden: u16,
    /// Outputs (3).
    pub outputs: u16,
    /// Seed of the training run.
    pub seed: u64,
    /// Hash of the training data set.
    pub train_hash: u64,
    /// Number of training points.
    pub train_points: u32,
    /// Training error reported by the trainer (e_ma, percent).
    pub train_error_pct: f32,
}

impl ModelInfo {
    /// The description of `blob` (its topology and training metadata).
    pub fn of(blob: &crate::runtime::blob::ModelBlob) -> ModelInfo {
        ModelInfo {
            inputs: blob.n_inputs() as u16,
            hidden: u16::from(blob.topology.hidden),
            outputs: blob.n_outputs() as u16,
            seed: blob.meta.seed,
            train_hash: blob.meta.train_hash,
            train_points: blob.meta.train_points,
            train_error_pct: blob.meta.train_error_pct,
        }
    }

    /// Whether two descriptions are of the same model: every field equal, the training error
    /// bit for bit.
    pub fn same_as(&self, other: &ModelInfo) -> bool {
        let bits = |m: &ModelInfo| ModelInfo { train_error_pct: 0.0, ..*m };
        bits(self) == bits(other)
            && self.train_error_pct.to_bits() == other.train_error_pct.to_bits()
    }
}

/// Answer to [`RequestBody::Info`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct InfoData {
    /// Firmware version.
    pub firmware: FirmwareVersion,
    /// Protocol version ([`PROTOCOL_VERSION`]).
    pub protocol: u16,
    /// The slot running, `None` in fallback mode.
    pub slot: Option<Slot>,
    /// Generation of the running blob, 0 in fallback mode.
    pub generation: u32,
    /// Network or fallback.
    pub mode: Mode,
    /// What boot found in slot A.
    pub slot_a: SlotStatus,
    /// What boot found in slot B.
    pub slot_b: SlotStatus,
    /// The running network, `None` in fallback mode.
    pub model: Option<ModelInfo>,
    /// The calibration of the traditional method used in fallback mode (built in).
    pub fallback: Calibration,
    /// Deepest the head's stack has been since reset, in bytes: the firmware paints the stack
    /// at reset and counts the words no longer painted. `None` where nothing measures it
    /// (the host-side [`crate::runtime::head`] logic).
    pub stack_peak: Option<u32>,
}

/// Which method produced an estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Source {
    /// The network.
    Network,
    /// The traditional method (fallback mode).
    Fallback,
}

/// Answer to [`RequestBody::Estimate`]: a point in the head frame (cm).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
pub struct EstimateData {
    /// X (cm).
    pub x: f32,
    /// Y (cm).
    pub y: f32,
    /// Z, depth (cm).
    pub z: f32,
    /// Method used.
    pub source: Source,
    /// False when the input lies outside the box of inputs seen in training (network), or the
    /// pixels lie outside the image the built-in calibration describes (fallback: `0 <= u <=
    /// 2 u0`, `0 <= v <= 2 v0`).
    pub in_range: bool,
}

/// The derive's encoding with one `f32` serializer (as `Calibration`'s): in a compact format
/// (postcard, the wire) the fields in order, the derive's bytes, with `x, y, z` from a loop
/// over an array; in a human-readable one the derive's map.
impl Serialize for EstimateData {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            use serde::ser::SerializeStruct;
            let mut st = s.serialize_struct("EstimateData", 5)?;
            st.serialize_field("x", &self.x)?;
            st.serialize_field("y", &self.y)?;
            st.serialize_field("z", &self.z)?;
            st.serialize_field("source", &self.source)?;
            st.serialize_field("in_range", &self.in_range)?;
            st.end()
        } else {
            ([self.x, self.y, self.z], self.source, self.in_range).serialize(s)
        }
    }
}

/// Answer to [`RequestBody::Look`]: the estimate and the joint targets the head now moves to.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LookData {
    /// The estimate of the point looked at.
    pub estimate: EstimateData,
    /// Joint targets of the move now under way (degrees, [`Axis`](crate::runtime::gaze::Axis) order,
    /// within the joint limits and on the 0.18° grid).
    pub target: Joints,
    /// True when a joint limit changed a target (the head cannot fixate exactly).
    pub limited: bool,
}

/// Answer to [`RequestBody::Bench`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BenchData {
    /// Inferences run (the request's count, capped by the head).
    pub count: u32,
    /// SysTick ticks for `count` inferences, minus the ticks of the same loop without inference.
    pub ticks: u32,
    /// SysTick ticks of the empty loop alone (the overhead subtracted).
    pub overhead_ticks: u32,
    /// SysTick input clock (Hz).
    pub tick_hz: u32,
}

/// Errors of encoding, decoding and framing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProtocolError {
    /// The output buffer is too small for the encoded message.
    BufferTooSmall,
    /// The frame is not valid COBS.
    BadCobs,
    /// The decoded bytes are not a valid postcard message (unknown variant, truncated...).
    BadMessage,
    /// The message decoded but bytes were left over in the frame.
    TrailingBytes,
    /// The frame exceeded the accumulator's buffer and was dropped.
    Oversize,
    /// An empty frame.
    Empty,
}

impl core::fmt::Display for ProtocolError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ProtocolError::BufferTooSmall => "output buffer too small for the frame",
            ProtocolError::BadCobs => "frame is not valid COBS",
            ProtocolError::BadMessage => "frame does not hold a valid message",
            ProtocolError::TrailingBytes => "frame has bytes after the message",
            ProtocolError::Oversize => "frame longer than the maximum frame length",
            ProtocolError::Empty => "empty frame",
        })
    }
}

/// Encodes `msg` as one frame (`COBS(postcard(msg)) 0x00`) into `buf`; returns the frame,
/// sentinel included.
pub fn encode<'a, T: Serialize>(msg: &T, buf: &'a mut [u8]) -> Result<&'a mut [u8], ProtocolError> {
    postcard::to_slice_cobs(msg, buf).map_err(|_| ProtocolError::BufferTooSmall)
}

/// Decodes one frame in place. `frame` is the COBS-encoded bytes, with or without the trailing
/// `0x00`; it is overwritten. The whole frame must hold exactly one message.
pub fn decode<'a, T: Deserialize<'a>>(frame: &'a mut [u8]) -> Result<T, ProtocolError> {
    let end = match frame.last() {
        Some(0) => frame.len() - 1,
        Some(_) => frame.len(),
        None => return Err(ProtocolError::Empty),
    };
    let frame = &mut frame[..end];
    if frame.is_empty() {
        return Err(ProtocolError::Empty);
    }
    if frame.contains(&0) {
        return Err(ProtocolError::BadCobs);
    }
    let len = cobs::decode_in_place(frame).map_err(|_| ProtocolError::BadCobs)?;
    let (msg, rest) =
        postcard::take_from_bytes::<T>(&frame[..len]).map_err(|_| ProtocolError::BadMessage)?;
    if rest.is_empty() {
        Ok(msg)
    } else {
        Err(ProtocolError::TrailingBytes)
    }
}

/// Encodes a request frame (see [`encode`]).
pub fn encode_request<'a>(req: &Request, buf: &'a mut [u8]) -> Result<&'a mut [u8], ProtocolError> {
    encode(req, buf)
}

/// Encodes a response frame (see [`encode`]).
pub fn encode_response<'a>(
    resp: &Response,
    buf: &'a mut [u8],
) -> Result<&'a mut [u8], ProtocolError> {
    encode(resp, buf)
}

/// Decodes a request frame in place (see [`decode`]).
pub fn decode_request(frame: &mut [u8]) -> Result<Request, ProtocolError> {
    decode(frame)
}

/// Decodes a response frame in place (see [`decode`]).
pub fn decode_response(frame: &mut [u8]) -> Result<Response, ProtocolError> {
    decode(frame)
}

/// Streaming frame splitter: bytes in, frames out.
///
/// Bytes are collected up to each `0x00`; the collected bytes (sentinel excluded) are one
/// frame. Empty frames (repeated `0x00`) are skipped. A frame longer than `N` bytes is dropped
/// byte by byte until the next `0x00`, which then yields one [`ProtocolError::Oversize`]; the
/// frame after it is received normally. Memory use is `N` bytes plus two words.
#[derive(Debug, Clone)]
pub struct FrameAccumulator<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Default for FrameAccumulator<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameAccumulator<N> {
    /// An empty accumulator.
    pub const fn new() -> Self {
        Self { buf: [0; N], len: 0, overflow: false }
    }

    /// Feeds one byte. Returns `Some(Ok(frame))` when `byte` ends a frame (the COBS bytes,
    /// without the sentinel, ready for [`decode`]), `Some(Err(Oversize))` when it ends an
    /// overlong frame, and `None` otherwise.
    pub fn push(&mut self, byte: u8) -> Option<Result<&mut [u8], ProtocolError>> {
        if byte == 0 {
            let len = core::mem::replace(&mut self.len, 0);
            if core::mem::replace(&mut self.overflow, false) {
                return Some(Err(ProtocolError::Oversize));
            }
            if len == 0 {
                return None;
            }
            return Some(Ok(&mut self.buf[..len]));
        }
        if self.overflow {
            return None;
        }
        if self.len == N {
            self.overflow = true;
            self.len = 0;
            return None;
        }
        self.buf[self.len] = byte;
        self.len += 1;
        None
    }

    /// Forgets a partly received frame (for example after a link timeout).
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Bytes of the frame received so far (0 while dropping an overlong frame).
    pub fn pending(&self) -> usize {
        self.len
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;

    #[test]
    fn model_info_compares_every_field_and_the_error_bit_for_bit() {
        let a = ModelInfo {
            inputs: 4,
            hidden: 5,
            outputs: 3,
            seed: 7,
            train_hash: 0xfeed,
            train_points: 72,
            train_error_pct: f32::NAN,
        };
        assert!(a.same_as(&a), "NaN errors of the same bits are the same model");
        assert!(!a.same_as(&ModelInfo { train_error_pct: -f32::NAN, ..a }));
        assert!(!a.same_as(&ModelInfo { train_points: 73, ..a }));
        assert!(!a.same_as(&ModelInfo { hidden: 12, ..a }));
        let b = ModelInfo { train_error_pct: 0.0, ..a };
        assert!(!b.same_as(&ModelInfo { train_error_pct: -0.0, ..b }), "0 and -0 differ in bits");
    }

    fn point(k: f32) -> StereoPoint {
        StereoPoint { u_l: 321.5 + k, v_l: -12.25 * k, u_r: f32::MAX, v_r: f32::MIN_POSITIVE }
    }

    fn largest_info() -> InfoData {
        InfoData {
            firmware: FirmwareVersion { major: u16::MAX, minor: u16::MAX, patch: u16::MAX },
            protocol: u16::MAX,
            slot: Some(Slot::B),
            generation: u32::MAX,
            mode: Mode::Network,
            slot_a: SlotStatus::UnsupportedTopology {
                inputs: u16::MAX,
                hidden: u16::MAX,
                outputs: u16::MAX,
            },
            slot_b: SlotStatus::UnsupportedTopology {
                inputs: u16::MAX,
                hidden: u16::MAX,
                outputs: u16::MAX,
            },
            model: Some(ModelInfo {
                inputs: u16::MAX,
                hidden: u16::MAX,
                outputs: u16::MAX,
                seed: u64::MAX,
                train_hash: u64::MAX,
                train_points: u32::MAX,
                train_error_pct: f32::MAX,
            }),
            fallback: Calibration {
                phi: f32::MAX,
                half_baseline: f32::MAX,
                u0: f32::MAX,
                v0: f32::MAX,
            },
            stack_peak: Some(u32::MAX),
        }
    }

    fn all_requests() -> [Request; 8] {
        [
            Request { id: 1, body: RequestBody::Ping },
            Request { id: 2, body: RequestBody::Info },
            Request { id: 3, body: RequestBody::Estimate(point(1.0)) },
            Request { id: u32::MAX, body: RequestBody::Look(point(-3.0)) },
            Request { id: 70_000, body: RequestBody::Home },
            Request { id: 9, body: RequestBody::Bench { point: point(0.5), count: u32::MAX } },
            Request {
                id: u32::MAX,
                body: RequestBody::Posture(Joints([
                    f32::MAX,
                    -f32::MAX,
                    f32::MIN_POSITIVE,
                    -0.0,
                    1e-30,
                ])),
            },
            Request { id: u32::MAX, body: RequestBody::State },
        ]
    }

    fn all_responses() -> [Response; 15] {
        let est = EstimateData {
            x: -1.5,
            y: f32::MAX,
            z: 165.000_01,
            source: Source::Fallback,
            in_range: false,
        };
        let mut info_fallback = largest_info();
        info_fallback.slot = None;
        info_fallback.mode = Mode::Fallback;
        info_fallback.model = None;
        info_fallback.slot_a = SlotStatus::Empty;
        info_fallback.slot_b = SlotStatus::Invalid(BlobError::UnsupportedVersion(u16::MAX));
        let bodies = [
            ResponseBody::Ready { protocol: PROTOCOL_VERSION },
            ResponseBody::Pong,
            ResponseBody::Info(largest_info()),
            ResponseBody::Info(info_fallback),
            ResponseBody::Estimate(est),
            ResponseBody::Look(LookData {
                estimate: est,
                target: Joints([f32::MAX, -f32::MAX, 0.18, -0.0, 1e-30]),
                limited: true,
            }),
            ResponseBody::Home,
            ResponseBody::Bench(BenchData {
                count: u32::MAX,
                ticks: u32::MAX,
                overhead_ticks: u32::MAX,
                tick_hz: u32::MAX,
            }),
            ResponseBody::Error(ErrorCode::Malformed),
            ResponseBody::Error(ErrorCode::Oversize),
            ResponseBody::Error(ErrorCode::NonFinite),
            ResponseBody::Error(ErrorCode::Unreachable),
            ResponseBody::Error(ErrorCode::NoSolution),
            ResponseBody::Error(ErrorCode::Unsupported),
            ResponseBody::State(StateData {
                joints: Joints([f32::MAX, -f32::MAX, 0.18, -0.0, 1e-30]),
                goal: Joints([-f32::MAX; 5]),
                ticks: u32::MAX,
                moving: true,
            }),
        ];
        bodies.map(|body| Response { id: u32::MAX, body })
    }

    #[test]
    fn requests_round_trip() {
        for req in all_requests() {
            let mut buf = [0u8; MAX_FRAME_LEN];
            let frame = encode_request(&req, &mut buf).unwrap();
            assert_eq!(frame.last(), Some(&0), "frame ends with the sentinel");
            assert!(!frame[..frame.len() - 1].contains(&0), "no zero inside");
            assert_eq!(decode_request(frame).unwrap(), req);
        }
    }

    #[test]
    fn responses_round_trip_and_fit_max_frame() {
        for resp in all_responses() {
            let mut buf = [0u8; MAX_FRAME_LEN];
            let frame = encode_response(&resp, &mut buf).unwrap();
            assert!(frame.len() <= MAX_FRAME_LEN);
            let mut copy = [0u8; MAX_FRAME_LEN];
            copy[..frame.len()].copy_from_slice(frame);
            let n = frame.len();
            assert_eq!(decode_response(&mut copy[..n]).unwrap(), resp);
            // Also without the sentinel, as the accumulator hands frames out.
            copy[..n].copy_from_slice(&buf[..n]);
            assert_eq!(decode_response(&mut copy[..n - 1]).unwrap(), resp);
        }
    }

    #[test]
    fn floats_travel_bit_for_bit() {
        let specials =
            [f32::NAN, -0.0, f32::INFINITY, f32::from_bits(1), f32::from_bits(0x7fc0_1234)];
        for v in specials {
            let resp = Response {
                id: 5,
                body: ResponseBody::Estimate(EstimateData {
                    x: v,
                    y: v,
                    z: v,
                    source: Source::Network,
                    in_range: true,
                }),
            };
            let mut buf = [0u8; MAX_FRAME_LEN];
            let frame = encode_response(&resp, &mut buf).unwrap();
            match decode_response(frame).unwrap().body {
                ResponseBody::Estimate(e) => {
                    assert_eq!(e.x.to_bits(), v.to_bits());
                    assert_eq!(e.z.to_bits(), v.to_bits());
                }
                other => panic!("wrong body {other:?}"),
            }
        }
    }

    #[test]
    fn small_buffer_is_an_error() {
        let resp = all_responses()[2];
        let mut buf = [0u8; 16];
        assert_eq!(encode_response(&resp, &mut buf), Err(ProtocolError::BufferTooSmall));
    }

    #[test]
    fn garbage_and_truncated_frames_are_errors() {
        let req = all_requests()[3];
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode_request(&req, &mut buf).unwrap().len();
        // Every truncation of the frame (sentinel excluded) fails to decode.
        for cut in 0..n - 1 {
            let mut t = [0u8; MAX_FRAME_LEN];
            t[..cut].copy_from_slice(&buf[..cut]);
            assert!(decode_request(&mut t[..cut]).is_err(), "truncated to {cut} bytes decoded");
        }
        // A frame with an extra byte appended is rejected, not silently accepted.
        let mut long = [0u8; MAX_FRAME_LEN];
        long[..n - 1].copy_from_slice(&buf[..n - 1]);
        long[n - 1] = 0x01;
        assert!(decode_request(&mut long[..n]).is_err());
        // Unknown request variant.
        let mut unknown = [0u8; 8];
        let f = encode(&(7u32, 200u8), &mut unknown).unwrap();
        assert_eq!(decode_request(f), Err(ProtocolError::BadMessage));
        // Empty and zero-containing frames.
        assert_eq!(decode_request(&mut []), Err(ProtocolError::Empty));
        assert_eq!(decode_request(&mut [0]), Err(ProtocolError::Empty));
        assert_eq!(decode_request(&mut [3, 0, 1]), Err(ProtocolError::BadCobs));
        // COBS code pointing past the end.
        assert_eq!(decode_request(&mut [9, 1, 2]), Err(ProtocolError::BadCobs));
    }

    #[test]
    fn decoding_arbitrary_bytes_never_panics() {
        // Deterministic pseudo-random garbage (xorshift), every length up to a frame.
        let mut s: u32 = 0x1234_5678;
        for len in 0..MAX_FRAME_LEN {
            for _ in 0..20 {
                let mut b = [0u8; MAX_FRAME_LEN];
                for x in b[..len].iter_mut() {
                    s ^= s << 13;
                    s ^= s >> 17;
                    s ^= s << 5;
                    *x = s as u8;
                }
                let _ = decode_request(&mut b[..len]);
                let _ = decode_response(&mut b[..len]);
            }
        }
    }

    /// Feeds `bytes` and collects what comes out: `Ok(request)` or the error.
    fn run<const N: usize>(
        acc: &mut FrameAccumulator<N>,
        bytes: &[u8],
    ) -> std::vec::Vec<Result<Request, ProtocolError>> {
        let mut out = std::vec::Vec::new();
        for &b in bytes {
            if let Some(r) = acc.push(b) {
                out.push(r.and_then(decode_request));
            }
        }
        out
    }

    #[test]
    fn accumulator_splits_a_stream() {
        let reqs = all_requests();
        let mut stream = std::vec::Vec::new();
        for r in &reqs {
            let mut buf = [0u8; MAX_FRAME_LEN];
            stream.extend_from_slice(encode_request(r, &mut buf).unwrap());
            stream.push(0); // Empty frames between messages are skipped.
        }
        let mut acc = FrameAccumulator::<MAX_FRAME_LEN>::new();
        let got = run(&mut acc, &stream);
        let want: std::vec::Vec<_> = reqs.iter().map(|r| Ok(*r)).collect();
        assert_eq!(got, want);
        assert_eq!(acc.pending(), 0);
    }

    #[test]
    fn accumulator_resyncs_after_garbage_and_oversize() {
        let good = all_requests()[2];
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = encode_request(&good, &mut buf).unwrap().to_vec();
        let mut acc = FrameAccumulator::<32>::new();

        // Oversize: 100 non-zero bytes, then the terminator, then a good frame.
        let mut stream = std::vec![0x55u8; 100];
        stream.push(0);
        stream.extend_from_slice(&frame);
        assert_eq!(run(&mut acc, &stream), std::vec![Err(ProtocolError::Oversize), Ok(good)]);

        // Exactly N bytes fit; N + 1 do not.
        let mut exact = std::vec![0x01u8; 32];
        exact.push(0);
        let got = run(&mut acc, &exact);
        assert_eq!(got.len(), 1);
        assert_ne!(got[0], Err(ProtocolError::Oversize));
        let mut over = std::vec![0x01u8; 33];
        over.push(0);
        assert_eq!(run(&mut acc, &over), std::vec![Err(ProtocolError::Oversize)]);

        // Garbage, then a truncated frame glued to the next terminator, then a good frame.
        let mut stream = std::vec![0xffu8, 0x03, 0x07, 0];
        stream.extend_from_slice(&frame[..frame.len() / 2]);
        stream.push(0);
        stream.extend_from_slice(&frame);
        let got = run(&mut acc, &stream);
        assert_eq!(got.len(), 3);
        assert!(got[0].is_err());
        assert!(got[1].is_err());
        assert_eq!(got[2], Ok(good));
    }

    #[test]
    fn accumulator_reset_drops_partial_frame() {
        let good = all_requests()[0];
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = encode_request(&good, &mut buf).unwrap().to_vec();
        let mut acc = FrameAccumulator::<MAX_FRAME_LEN>::new();
        assert!(run(&mut acc, &[0x42, 0x42]).is_empty());
        assert_eq!(acc.pending(), 2);
        acc.reset();
        assert_eq!(run(&mut acc, &frame), std::vec![Ok(good)]);
    }
}
