//! The head controller's decisions, without I/O: which weight slot boots, how a point becomes
//! an estimate, and what `Info` reports.
//!
//! The firmware hands [`boot`] the raw bytes of both weight slots, wraps the returned [`Boot`]
//! in a [`Head`] (with the gaze controller) and then only moves bytes: every request is
//! answered by [`Head::respond`] and every control tick is [`Head::tick`], so the host tests
//! the exact logic the head runs.
//!
//! A slot is run only if its blob validates *and* the head can supply its inputs and use its
//! outputs: inputs [`InputKind::Stereo`] (the four pixels) or [`InputKind::StereoJoints`]
//! (the four pixels, then the head's own five joint angles in degrees: the gaze controller's
//! current setpoints, see [`Head::joints`]), outputs [`OutputKind::Xyz`] (`Look` needs all
//! three), any hidden count the blob allows. A 4-5-3 net of any family
//! ([`NET_INPUTS`]-[`NET_HIDDEN`]-[`NET_OUTPUTS`]) runs on the fixed-size fast path
//! [`crate::runtime::mlp::FixedMlp`], copied out of the blob at boot (the bits of
//! [`crate::runtime::mlp::infer_flat`]); every
//! other runnable topology on the runtime-sized [`crate::runtime::mlp::infer_flat`] (the same
//! bits as the blob's own [`ModelBlob::infer`]); either way the blob's family maps the outputs to cm
//! ([`crate::runtime::mlp::OutputMap`]). Anything else counts as not runnable, and with no runnable slot the
//! head falls back to the traditional method with [`Calibration::BUILT_IN`].

use crate::runtime::blob::{self, InputKind, ModelBlob, OutputKind};
use crate::runtime::gaze::{self, GazeConfig, GazeError, Joints};
use crate::runtime::layout::Slot;
use crate::runtime::mlp::{self, FixedMlp, Mlp, MlpError};
use crate::runtime::protocol::{
    self, ErrorCode, EstimateData, FirmwareVersion, InfoData, LookData, Mode, ModelInfo,
    ProtocolError, Request, RequestBody, Response, ResponseBody, SlotStatus, Source, StateData,
    StereoPoint, PROTOCOL_VERSION,
};
use crate::runtime::slots::{self, SlotState};
use crate::runtime::traditional::{self, Calibration};
use crate::runtime::trajectory::{ConfigError, ControllerConfig, GazeController};

/// Inputs of the thesis' network: `u_l, v_l, u_r, v_r`.
pub const NET_INPUTS: usize = 4;
/// Hidden neurons of the thesis' 4-5-3 network (the fixed-size fast path).
pub const NET_HIDDEN: usize = 5;
/// Outputs of every network the head runs: `X, Y, Z`.
pub const NET_OUTPUTS: usize = 3;
/// Inputs of a posture-aware network: the four pixels, then the five joint angles.
pub const JOINTS_NET_INPUTS: usize = 9;

/// The thesis' network as a fixed-size [`Mlp`] (the same arithmetic as the head's fast path).
pub type HeadMlp = Mlp<NET_INPUTS, NET_HIDDEN, NET_OUTPUTS>;
/// The head's fast path: a 4-5-3 net of any family in fixed-size arrays.
pub type HeadFixedMlp = FixedMlp<NET_INPUTS, NET_HIDDEN, NET_OUTPUTS>;

/// A runnable network loaded from a slot, with what `Estimate` and `Info` need of its blob.
#[derive(Debug, Clone, PartialEq)]
pub struct Network {
    /// The decoded blob: weights, scaling and training box.
    pub blob: ModelBlob,
    /// Whether the blob is a 4-5-3 net (pixels in, XYZ out, any family), run on the
    /// fixed-size fast path [`Network::fixed`].
    pub fast: bool,
    /// The fast path's copy of the blob's net (`Some` exactly when `fast`).
    pub fixed: Option<HeadFixedMlp>,
    /// The slot it came from.
    pub slot: Slot,
    /// The blob's generation.
    pub generation: u32,
    /// Metadata for `Info`.
    pub model: ModelInfo,
}

impl Network {
    /// The network of a decoded (hence validated) blob loaded from `slot`, or `None` if the
    /// head cannot supply its inputs or use its outputs (see the module documentation).
    pub fn new(slot: Slot, blob: ModelBlob) -> Option<Network> {
        let (fast, model) = Network::check(&blob)?;
        Some(Network {
            generation: blob.generation,
            fixed: fixed_of(fast, &blob),
            blob,
            fast,
            slot,
            model,
        })
    }

    /// What [`Network::new`] decides, by reference: `(fast, model)` if the head can run
    /// `blob`, `None` if not.
    fn check(blob: &ModelBlob) -> Option<(bool, ModelInfo)> {
        let suppliable =
            matches!(blob.topology.inputs, InputKind::Stereo | InputKind::StereoJoints);
        if !suppliable || blob.topology.outputs != OutputKind::Xyz {
            return None;
        }
        let model = ModelInfo::of(blob);
        let fast = blob.topology.inputs == InputKind::Stereo
            && usize::from(blob.topology.hidden) == NET_HIDDEN
            && blob.n_outputs() == NET_OUTPUTS;
        Some((fast, model))
    }

    /// The network's inputs for pixels `px` seen at posture `joints`: the pixels, then (for
    /// posture-aware nets) the joint angles. Returns the buffer and the number of inputs used.
    fn inputs(&self, px: &[f32; NET_INPUTS], joints: &Joints) -> ([f32; JOINTS_NET_INPUTS], usize) {
        let mut x = [0.0f32; JOINTS_NET_INPUTS];
        x[..NET_INPUTS].copy_from_slice(px);
        x[NET_INPUTS..].copy_from_slice(&joints.0);
        (x, self.blob.n_inputs().min(JOINTS_NET_INPUTS))
    }

    /// One inference: `[X, Y, Z]` (cm) of `[u_l, v_l, u_r, v_r]` seen at posture `joints`
    /// (used by posture-aware nets only). Not generic, so the firmware's `Estimate` and its
    /// `Bench` run this one compiled function.
    #[inline(never)]
    pub fn infer(
        &self,
        px: &[f32; NET_INPUTS],
        joints: &Joints,
    ) -> Result<[f32; NET_OUTPUTS], MlpError> {
        let mut y = [0.0f32; NET_OUTPUTS];
        let inputs;
        let x: &[f32] = if let Some(fixed) = &self.fixed {
            // Pixels in: the output frame reads no joint inputs.
            fixed.infer_into(px, &mut y)?;
            px
        } else {
            // `ModelBlob::infer`'s two steps, the output map and frame shared with the fast
            // path.
            inputs = self.inputs(px, joints);
            let x = &inputs.0[..inputs.1];
            mlp::infer_flat(&self.blob.flat(), x, &mut y)?;
            x
        };
        self.blob.finish(x, &mut y)?;
        Ok(y)
    }

    /// Whether the inputs lie inside the box seen in training and the estimate `y` (cm, head
    /// frame) inside the output box ([`outputs_in_range`]).
    pub fn in_range(
        &self,
        px: &[f32; NET_INPUTS],
        joints: &Joints,
        y: &[f32; NET_OUTPUTS],
    ) -> bool {
        let (x, n) = self.inputs(px, joints);
        self.blob.in_range(&x[..n]) && outputs_in_range(&self.blob, &x[..n], y)
    }
}

/// How far an estimate may lie outside the output box of training before it is flagged, in
/// units of the output's scale (the training outputs span `offset +- scale` at most, for
/// linear and sigmoid outputs alike): `offset +- OUTPUT_MARGIN * |scale|`.
pub const OUTPUT_MARGIN: f32 = 4.0;

/// No estimate beyond this many cm (a kilometre) is in range, whatever the blob says (`hvs
/// train` refuses ground truth beyond it).
pub const PLAUSIBLE_CM: f32 = 1e5;

/// Whether the outputs `y` of `blob` for inputs `x` (in its output order, cm, head frame) lie
/// within [`OUTPUT_MARGIN`] output scales of the box seen in training, and within
/// [`PLAUSIBLE_CM`]. A damaged but
/// CRC-valid blob (a weight of 3.4e38) gives estimates far outside it. The blob keeps the
/// output normalisation (`out_offset`, `out_scale`, in the family's output space: X, Y, Z for
/// the thesis family, X/Z, Y/Z, 1/Z for inverse depth), not the training output box itself;
/// the box derived from it holds the training outputs for linear and sigmoid outputs, and the
/// estimate is taken back to that space (and to the model's [`blob::OutputFrame`]) to be compared.
pub fn outputs_in_range(blob: &ModelBlob, x: &[f32], y: &[f32]) -> bool {
    if y.len() != blob.out_offset.len() || !y.iter().all(|v| libm::fabsf(*v) <= PLAUSIBLE_CM) {
        return false;
    }
    let back: [f32; 3];
    let back_z: [f32; 1];
    let o: &[f32] = match y {
        [a, b, c] => {
            let [a, b, c] = blob.frame.from_head(x, [*a, *b, *c]);
            back = match blob.family.output_map {
                mlp::OutputMap::InverseDepth => [a / c, b / c, 1.0 / c],
                mlp::OutputMap::Direct => [a, b, c],
            };
            &back
        }
        // A Z-only net: its one output is 1/Z for the inverse-depth family.
        [z] => {
            back_z = match blob.family.output_map {
                mlp::OutputMap::InverseDepth => [1.0 / *z],
                mlp::OutputMap::Direct => [*z],
            };
            &back_z
        }
        _ => y,
    };
    let within = |(v, (off, scale)): (&f32, (&f32, &f32))| {
        libm::fabsf(*v - *off) <= OUTPUT_MARGIN * libm::fabsf(*scale)
    };
    // The depth (Z, or 1/Z: the last output) of a net trained on points in front of the
    // cameras only is in front: the margin does not reach through zero (past infinity, for
    // 1/Z) to a point behind them.
    let in_front = match (o.last(), blob.out_offset.last(), blob.out_scale.last()) {
        (Some(v), Some(off), Some(scale)) => *off - libm::fabsf(*scale) < 0.0 || *v > 0.0,
        _ => true,
    };
    in_front && o.iter().zip(blob.out_offset.iter().zip(blob.out_scale.iter())).all(within)
}

/// How the head computes depth after boot.
// No allocator to box the network into; one instance lives for the whole run.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Estimator {
    /// A network from a weight slot.
    Network(Network),
    /// The traditional method with this calibration.
    Fallback(Calibration),
}

/// The result of boot: what each slot held and what runs.
#[derive(Debug, Clone, PartialEq)]
pub struct Boot {
    /// What slot A held.
    pub slot_a: SlotStatus,
    /// What slot B held.
    pub slot_b: SlotStatus,
    /// What runs.
    pub estimator: Estimator,
}

/// Classifies one slot's bytes: what `Info` reports, what the boot choice sees and, if the
/// blob is runnable ([`Network::new`]), its network.
fn classify(slot: Slot, bytes: &[u8]) -> (SlotStatus, SlotState, Option<Network>) {
    let blob = match blob::decode(bytes) {
        Ok(b) => b,
        Err(blob::BlobError::BadMagic) => return (SlotStatus::Empty, SlotState::Empty, None),
        Err(e) => return (SlotStatus::Invalid(e), SlotState::Invalid(e), None),
    };
    let (status, state) = runnable(&blob);
    (status, state, Network::new(slot, blob))
}

/// What a decoded blob counts as: valid if the head can run it ([`Network::check`]).
fn runnable(blob: &ModelBlob) -> (SlotStatus, SlotState) {
    let generation = blob.generation;
    if Network::check(blob).is_some() {
        return (SlotStatus::Valid { generation }, SlotState::Valid { generation });
    }
    (
        SlotStatus::UnsupportedTopology {
            inputs: blob.n_inputs() as u16,
            hidden: u16::from(blob.topology.hidden),
            outputs: blob.n_outputs() as u16,
        },
        SlotState::Unrunnable { generation },
    )
}

/// `est`'s network, made an [`Estimator::Network`] with a placeholder blob if it was not
/// one: the place boot decodes into.
#[inline(never)]
/// The fast path's copy of `blob`'s net if `fast` (a 4-5-3 net, see [`Network::check`]).
fn fixed_of(fast: bool, blob: &ModelBlob) -> Option<HeadFixedMlp> {
    let mut f = None;
    set_fixed(&mut f, fast, blob);
    f
}

/// [`fixed_of`] into `place`, copying the net in place (no copy of it on the stack).
fn set_fixed(place: &mut Option<HeadFixedMlp>, fast: bool, blob: &ModelBlob) {
    let f = place.insert(FixedMlp::ZERO);
    if !fast || f.load(&blob.flat()).is_err() {
        *place = None;
    }
}

fn network_place(est: &mut Estimator) -> &mut Network {
    if let Estimator::Fallback(_) = *est {
        *est = Estimator::Network(Network {
            blob: blob::placeholder(),
            fast: false,
            fixed: None,
            slot: Slot::A,
            generation: 0,
            model: ModelInfo {
                inputs: 0,
                hidden: 0,
                outputs: 0,
                seed: 0,
                train_hash: 0,
                train_points: 0,
                train_error_pct: 0.0,
            },
        });
    }
    match est {
        Estimator::Network(n) => n,
        Estimator::Fallback(_) => unreachable!("set to a network just above"),
    }
}

/// [`classify`]'s status and state, decoding into `place` ([`blob::decode_into`]);
/// on `Valid`, `place` holds the decoded blob.
fn classify_in_place(bytes: &[u8], place: &mut ModelBlob) -> (SlotStatus, SlotState) {
    match blob::decode_into(bytes, place) {
        Ok(()) => runnable(place),
        Err(blob::BlobError::BadMagic) => (SlotStatus::Empty, SlotState::Empty),
        Err(e) => (SlotStatus::Invalid(e), SlotState::Invalid(e)),
    }
}

/// Classifies one slot's bytes and, if the blob is runnable, loads its network.
pub fn load_slot(slot: Slot, bytes: &[u8]) -> (SlotStatus, Option<Network>) {
    let (status, _, net) = classify(slot, bytes);
    (status, net)
}

/// What one slot's raw bytes count as in the boot choice: [`SlotState::Valid`] only if the blob
/// validates *and* the head can run it ([`Network::new`]). [`boot`] chooses with exactly these
/// states and [`slots::choose_boot`]; `hvs flash` plans its write with them, so the host's
/// "running slot" is the one the head runs.
pub fn slot_state(bytes: &[u8]) -> SlotState {
    classify(Slot::A, bytes).1
}

/// Boots from the raw bytes of both slots (each at least the blob's framed length; trailing
/// bytes are ignored). The runnable slot with the higher generation runs (A on a tie, the
/// rule of [`slots::choose_boot`] over [`slot_state`]); with none, the traditional method with
/// [`Calibration::BUILT_IN`].
///
/// The firmware boots with [`Boot::boot_in_place`] instead (same result, smaller stack).
pub fn boot(slot_a: &[u8], slot_b: &[u8]) -> Boot {
    let mut b = Boot {
        slot_a: SlotStatus::Empty,
        slot_b: SlotStatus::Empty,
        estimator: Estimator::Fallback(Calibration::BUILT_IN),
    };
    b.boot_in_place(slot_a, slot_b);
    b
}

impl Boot {
    /// [`boot`] into `self`, replacing what it held, with every blob decoded in place
    /// ([`blob::decode_into`]) into the network `self` will run: the head keeps its `Boot` in
    /// static RAM, so boot copies no decoded blob through the stack. The same result as
    /// [`boot`] (tested).
    pub fn boot_in_place(&mut self, slot_a: &[u8], slot_b: &[u8]) {
        let net = network_place(&mut self.estimator);
        let (status_a, state_a) = classify_in_place(slot_a, &mut net.blob);
        let (status_b, state_b) = classify_in_place(slot_b, &mut net.blob);
        self.slot_a = status_a;
        self.slot_b = status_b;
        let (slot, bytes) = match slots::choose_boot(state_a, state_b) {
            Some(Slot::A) => (Slot::A, slot_a),
            Some(Slot::B) => (Slot::B, slot_b),
            None => {
                self.estimator = Estimator::Fallback(Calibration::BUILT_IN);
                return;
            }
        };
        // Slot B was decoded last, maybe partly: if A runs, decode it once more (it decoded
        // before, so it does again).
        if slot == Slot::A {
            let _ = blob::decode_into(bytes, &mut net.blob);
        }
        match Network::check(&net.blob) {
            Some((fast, model)) => {
                net.fast = fast;
                set_fixed(&mut net.fixed, fast, &net.blob);
                net.slot = slot;
                net.generation = net.blob.generation;
                net.model = model;
            }
            None => self.estimator = Estimator::Fallback(Calibration::BUILT_IN),
        }
    }
}

impl Boot {
    /// The `Info` answer for firmware `version`.
    pub fn info(&self, version: FirmwareVersion) -> InfoData {
        let (slot, generation, mode, model) = match &self.estimator {
            Estimator::Network(n) => (Some(n.slot), n.generation, Mode::Network, Some(n.model)),
            Estimator::Fallback(_) => (None, 0, Mode::Fallback, None),
        };
        let fallback = match &self.estimator {
            Estimator::Fallback(c) => *c,
            Estimator::Network(_) => Calibration::BUILT_IN,
        };
        InfoData {
            firmware: version,
            protocol: PROTOCOL_VERSION,
            slot,
            generation,
            mode,
            slot_a: self.slot_a,
            slot_b: self.slot_b,
            model,
            fallback,
            stack_peak: None,
        }
    }

    /// The estimate of `p` with the head at home (as it is after boot, before any `Look`),
    /// or why there is none.
    pub fn estimate(&self, p: &StereoPoint) -> Result<EstimateData, ErrorCode> {
        self.estimator.estimate(p, &Joints::HOME)
    }
}

/// The answer to a request that failed before its id could be read.
pub fn frame_error(code: ErrorCode) -> Response {
    Response { id: crate::runtime::protocol::UNSOLICITED_ID, body: ResponseBody::Error(code) }
}

/// What the head does with one result of [`FrameAccumulator::push`]: the request in the frame,
/// or the response to send at once (with [`UNSOLICITED_ID`](crate::runtime::protocol::UNSOLICITED_ID)):
/// [`ErrorCode::Oversize`] for a frame longer than the accumulator's buffer,
/// [`ErrorCode::Malformed`] for anything that is not exactly one request (bad COBS, unknown
/// variant, truncated, trailing bytes).
///
/// [`FrameAccumulator::push`]: crate::runtime::protocol::FrameAccumulator::push
pub fn read_frame(frame: Result<&mut [u8], ProtocolError>) -> Result<Request, Response> {
    match frame.and_then(protocol::decode_request) {
        Ok(req) => Ok(req),
        Err(ProtocolError::Oversize) => Err(frame_error(ErrorCode::Oversize)),
        Err(_) => Err(frame_error(ErrorCode::Malformed)),
    }
}

impl Boot {
    /// Answers the requests that need no movement, with the head at home (`Look`, `Home` and
    /// `Bench` answer [`ErrorCode::Unsupported`] here: see [`Head::respond`]).
    pub fn respond(&self, req: &Request, version: FirmwareVersion) -> Response {
        let body = match req.body {
            RequestBody::Ping => ResponseBody::Pong,
            RequestBody::Info => ResponseBody::Info(self.info(version)),
            RequestBody::Estimate(p) => match self.estimate(&p) {
                Ok(e) => ResponseBody::Estimate(e),
                Err(c) => ResponseBody::Error(c),
            },
            RequestBody::Look(_)
            | RequestBody::Home
            | RequestBody::Bench { .. }
            | RequestBody::Posture(_)
            | RequestBody::State => ResponseBody::Error(ErrorCode::Unsupported),
        };
        Response { id: req.id, body }
    }
}

/// The head: what boot chose, the gaze settings and the setpoint generator.
#[derive(Debug, Clone, PartialEq)]
pub struct Head {
    /// What boot found and runs.
    pub boot: Boot,
    /// Fixation settings (neck/eye split, limits).
    pub gaze: GazeConfig,
    /// Trajectories of the five axes.
    pub controller: GazeController,
    /// Control ticks since boot (wrapping): the clock [`StateData::ticks`] reports.
    pub ticks: u32,
}

impl Head {
    /// A head at rest at home. Fails if the controller settings are unusable.
    pub fn new(
        boot: Boot,
        gaze: GazeConfig,
        controller: &ControllerConfig,
    ) -> Result<Head, ConfigError> {
        Ok(Head { boot, gaze, controller: GazeController::new(controller)?, ticks: 0 })
    }

    /// Answers `req`; `Look` and `Home` start a move. `Bench` is the firmware's (answered
    /// [`ErrorCode::Unsupported`] here).
    pub fn respond(&mut self, req: &Request, version: FirmwareVersion) -> Response {
        let body = match req.body {
            RequestBody::Look(p) => match self.look(&p) {
                Ok(l) => ResponseBody::Look(l),
                Err(c) => ResponseBody::Error(c),
            },
            RequestBody::Home => {
                self.controller.home();
                ResponseBody::Home
            }
            RequestBody::Estimate(p) => match self.estimate(&p) {
                Ok(e) => ResponseBody::Estimate(e),
                Err(c) => ResponseBody::Error(c),
            },
            RequestBody::Posture(j) if j.0.iter().any(|a| a.is_infinite()) => {
                ResponseBody::Error(ErrorCode::NonFinite)
            }
            RequestBody::Posture(j) => {
                // `start` clamps every joint to its limits; a NaN keeps that joint's goal.
                self.controller.start(&j);
                ResponseBody::State(self.state())
            }
            RequestBody::State => ResponseBody::State(self.state()),
            _ => return self.boot.respond(req, version),
        };
        Response { id: req.id, body }
    }

    /// The posture the head reports to posture-aware networks: the gaze controller's current
    /// setpoints (whole drive steps, within the joint limits), degrees.
    pub fn joints(&self) -> Joints {
        self.controller.setpoint()
    }

    /// The estimate of `p`, seen at the current posture ([`Head::joints`]).
    pub fn estimate(&self, p: &StereoPoint) -> Result<EstimateData, ErrorCode> {
        self.boot.estimator.estimate(p, &self.joints())
    }

    /// Estimates `p` (at the current posture), fixates the estimate and starts the move there.
    pub fn look(&mut self, p: &StereoPoint) -> Result<LookData, ErrorCode> {
        let estimate = self.estimate(p)?;
        let fix =
            gaze::fixate(&self.gaze, [estimate.x, estimate.y, estimate.z]).map_err(
                |e| match e {
                    GazeError::NonFinite => ErrorCode::NonFinite,
                    GazeError::BehindHead | GazeError::TooClose => ErrorCode::Unreachable,
                },
            )?;
        self.controller.start(&fix.joints);
        Ok(LookData { estimate, target: self.goal(), limited: fix.clamped })
    }

    /// Where the setpoints of the current move settle: its goal on the step grid, within the
    /// controller's limits (the ones every setpoint obeys).
    pub fn goal(&self) -> Joints {
        self.controller.settled_goal()
    }

    /// One control tick: the next setpoint (degrees) for the servos.
    pub fn tick(&mut self) -> Joints {
        self.ticks = self.ticks.wrapping_add(1);
        self.controller.tick()
    }

    /// The posture and clock [`RequestBody::State`] reports.
    pub fn state(&self) -> StateData {
        StateData {
            joints: self.joints(),
            goal: self.goal(),
            ticks: self.ticks,
            moving: self.controller.is_moving(),
        }
    }
}

/// The head's main loop without its I/O: what the firmware's `main` does between the USART,
/// the control clock and the servos, and what every simulated head does, so both run one
/// definition of the arming rule.
///
/// The servos are left alone until the first `Look` or `Home` is answered: their position at
/// power-up is unknown, and commanding home unasked could swing the head. From then on every
/// control tick's setpoint goes to them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MainLoop {
    armed: bool,
}

/// One control tick of [`MainLoop::tick`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// The setpoint of this tick (degrees, within the limits, on the step grid).
    pub setpoint: Joints,
    /// Whether it goes to the servos (the loop is armed).
    pub command: bool,
}

impl MainLoop {
    /// A loop at power-up: not armed.
    pub const fn new() -> MainLoop {
        MainLoop { armed: false }
    }

    /// True once a `Look` or `Home` was answered.
    pub const fn armed(&self) -> bool {
        self.armed
    }

    /// One control tick of `head`: its next setpoint, and whether to command it.
    pub fn tick(&self, head: &mut Head) -> Tick {
        Tick { setpoint: head.tick(), command: self.armed }
    }

    /// A received frame (from [`crate::runtime::protocol::FrameAccumulator::push`]): `answer`'s
    /// response to a well-formed request (the first `Look` or `Home` answered arms the loop),
    /// or the error response to send for a bad frame (unsolicited: [`frame_error`]).
    pub fn frame(
        &mut self,
        frame: Result<&mut [u8], ProtocolError>,
        answer: impl FnOnce(&Request) -> Response,
    ) -> Response {
        match read_frame(frame) {
            Ok(req) => {
                let resp = answer(&req);
                self.armed |= matches!(resp.body, ResponseBody::Look(_) | ResponseBody::Home)
                    || matches!(
                        (req.body, resp.body),
                        (RequestBody::Posture(_), ResponseBody::State(_))
                    );
                resp
            }
            Err(e) => e,
        }
    }
}

impl Estimator {
    /// The estimate of `p` seen at posture `joints` (which only posture-aware networks use),
    /// or why there is none.
    pub fn estimate(&self, p: &StereoPoint, joints: &Joints) -> Result<EstimateData, ErrorCode> {
        if !p.is_finite() {
            return Err(ErrorCode::NonFinite);
        }
        let x = p.to_array();
        match self {
            Estimator::Network(n) => {
                let [x_cm, y_cm, z_cm] = n.infer(&x, joints).map_err(|e| match e {
                    MlpError::NonFiniteInput => ErrorCode::NonFinite,
                    MlpError::NonFiniteOutput | MlpError::Shape => ErrorCode::NoSolution,
                })?;
                let in_range = n.in_range(&x, joints, &[x_cm, y_cm, z_cm]);
                Ok(EstimateData { x: x_cm, y: y_cm, z: z_cm, source: Source::Network, in_range })
            }
            Estimator::Fallback(cal) => {
                let [x_cm, y_cm, z_cm] =
                    traditional::traditional_xyz(cal, &x).map_err(|e| match e {
                        traditional::TriError::NonFinite => ErrorCode::NonFinite,
                        _ => ErrorCode::NoSolution,
                    })?;
                let in_image = |u: f32, c: f32| u >= 0.0 && u <= 2.0 * c;
                let in_range = in_image(p.u_l, cal.u0)
                    && in_image(p.u_r, cal.u0)
                    && in_image(p.v_l, cal.v0)
                    && in_image(p.v_r, cal.v0);
                Ok(EstimateData { x: x_cm, y: y_cm, z: z_cm, source: Source::Fallback, in_range })
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    extern crate std;

    use super::*;
    use crate::runtime::blob::{BlobError, MAX_BLOB_LEN};
    use crate::runtime::gaze::Axis;
    use crate::test_support::SampleSpec;
    use std::vec::Vec as StdVec;

    /// A posture-aware 9-`hidden`-3 sample blob (pixels and joint angles).
    fn sample_joints(hidden: u8, generation: u32, seed: u64) -> ModelBlob {
        SampleSpec::THESIS
            .inputs(InputKind::StereoJoints)
            .hidden(hidden)
            .generation(generation)
            .seed(seed)
            .build()
    }

    /// A 4-`hidden`-3 sample blob.
    fn sample(hidden: u8, generation: u32, seed: u64) -> ModelBlob {
        SampleSpec::THESIS.hidden(hidden).generation(generation).seed(seed).build()
    }

    fn bytes(b: &ModelBlob) -> StdVec<u8> {
        let mut buf = std::vec![0u8; MAX_BLOB_LEN];
        let n = b.encode(&mut buf).unwrap();
        buf.truncate(n);
        // Flash after a blob: whatever was there before (here 0x00 as in QEMU).
        buf.resize(MAX_BLOB_LEN, 0);
        buf
    }

    fn corrupt(mut b: StdVec<u8>) -> StdVec<u8> {
        b[20] ^= 0x10;
        b
    }

    const P: StereoPoint = StereoPoint { u_l: 330.0, v_l: 241.0, u_r: 310.0, v_r: 239.0 };

    #[test]
    fn higher_generation_runs_and_ties_go_to_a() {
        let a = bytes(&sample(5, 3, 1));
        let b = bytes(&sample(5, 4, 2));
        let boot_ab = boot(&a, &b);
        let Estimator::Network(n) = &boot_ab.estimator else { panic!("fallback") };
        assert_eq!((n.slot, n.generation, n.model.seed), (Slot::B, 4, 2));
        let boot_ba = boot(&b, &a);
        let Estimator::Network(n) = &boot_ba.estimator else { panic!("fallback") };
        assert_eq!((n.slot, n.generation), (Slot::A, 4));
        let tie = boot(&bytes(&sample(5, 4, 9)), &b);
        let Estimator::Network(n) = &tie.estimator else { panic!("fallback") };
        assert_eq!((n.slot, n.model.seed), (Slot::A, 9));
    }

    const V0_1_0: FirmwareVersion = FirmwareVersion { major: 0, minor: 1, patch: 0 };

    #[test]
    fn corrupted_slot_is_never_run() {
        let a = corrupt(bytes(&sample(5, 9, 1)));
        let b = bytes(&sample(5, 2, 2));
        let got = boot(&a, &b);
        assert_eq!(got.slot_a, SlotStatus::Invalid(BlobError::BadCrc));
        assert_eq!(got.slot_b, SlotStatus::Valid { generation: 2 });
        let info = got.info(V0_1_0);
        assert_eq!((info.slot, info.generation, info.mode), (Some(Slot::B), 2, Mode::Network));

        let both = boot(&a, &corrupt(b));
        assert_eq!(both.estimator, Estimator::Fallback(Calibration::BUILT_IN));
        let info = both.info(V0_1_0);
        assert_eq!((info.slot, info.mode, info.model), (None, Mode::Fallback, None));
        // Fallback still answers, with the traditional method's numbers.
        let e = both.estimate(&P).unwrap();
        let want = traditional::traditional_xyz(&Calibration::BUILT_IN, &P.to_array()).unwrap();
        assert_eq!([e.x, e.y, e.z], want);
        assert_eq!(e.source, Source::Fallback);
        assert!(e.in_range);
    }

    #[test]
    fn empty_slots_and_unsupported_topology_fall_back() {
        let empty = std::vec![0xffu8; MAX_BLOB_LEN];
        let zero = std::vec![0u8; MAX_BLOB_LEN];
        let got = boot(&empty, &zero);
        assert_eq!((got.slot_a, got.slot_b), (SlotStatus::Empty, SlotStatus::Empty));
        assert!(matches!(got.estimator, Estimator::Fallback(_)));

        // A valid blob with Z-only outputs (the head cannot Look with it) and a higher
        // generation loses to a runnable 4-5-3 one.
        let z_only = z_only(50);
        let got = boot(&z_only, &bytes(&sample(5, 1, 2)));
        assert_eq!(
            got.slot_a,
            SlotStatus::UnsupportedTopology { inputs: 4, hidden: 5, outputs: 1 }
        );
        let Estimator::Network(n) = &got.estimator else { panic!("fallback") };
        assert_eq!(n.slot, Slot::B);
        let got = boot(&z_only, &empty);
        assert!(matches!(got.estimator, Estimator::Fallback(_)));
    }

    /// A valid blob with Z-only outputs: the head does not run it.
    fn z_only(generation: u32) -> StdVec<u8> {
        bytes(&SampleSpec::THESIS.outputs(OutputKind::Z).generation(generation).seed(1).build())
    }

    #[test]
    fn the_host_plan_sees_the_slot_boot_runs() {
        use crate::runtime::slots::{plan_write, SlotRequest};
        // A: Z-only at generation 9, B: runnable at 7. The head runs B, so `hvs flash`'s
        // plan (on the same bytes) must leave B alone and write A.
        let (a, b) = (z_only(9), bytes(&sample(5, 7, 2)));
        assert_eq!(slot_state(&a), SlotState::Unrunnable { generation: 9 });
        assert_eq!(network(&boot(&a, &b)).slot, Slot::B);
        let p = plan_write(slot_state(&a), slot_state(&b), SlotRequest::Auto).unwrap();
        assert_eq!((p.slot, p.generation, p.running), (Slot::A, 8, Some(Slot::B)));
        // Every combination: the plan's running slot is the one boot runs, and it never
        // targets it.
        let contents = [
            StdVec::new(),
            std::vec![0xffu8; MAX_BLOB_LEN],
            corrupt(bytes(&sample(5, 4, 3))),
            z_only(9),
            z_only(2),
            bytes(&sample(5, 1, 4)),
            bytes(&sample(7, 7, 5)),
            bytes(&sample_joints(9, 3, 6)),
        ];
        for a in &contents {
            for b in &contents {
                let booted = boot(a, b).info(V).slot;
                let p = plan_write(slot_state(a), slot_state(b), SlotRequest::Auto).unwrap();
                assert_eq!(p.running, booted);
                assert_ne!(Some(p.slot), booted);
            }
        }
    }

    /// [`boot`] as it was before it decoded in place: every slot through [`classify`].
    fn boot_by_value(slot_a: &[u8], slot_b: &[u8]) -> Boot {
        let (status_a, state_a, net_a) = classify(Slot::A, slot_a);
        let (status_b, state_b, net_b) = classify(Slot::B, slot_b);
        let estimator = match slots::choose_boot(state_a, state_b) {
            Some(Slot::A) => net_a.map(Estimator::Network),
            Some(Slot::B) => net_b.map(Estimator::Network),
            None => None,
        }
        .unwrap_or(Estimator::Fallback(Calibration::BUILT_IN));
        Boot { slot_a: status_a, slot_b: status_b, estimator }
    }

    #[test]
    fn booting_in_place_equals_booting_by_value() {
        let mut half = bytes(&sample(5, 3, 8));
        half.truncate(40);
        let contents = [
            StdVec::new(),
            std::vec![0xffu8; MAX_BLOB_LEN],
            corrupt(bytes(&sample(5, 4, 3))),
            half,
            z_only(9),
            z_only(2),
            bytes(&sample(5, 1, 4)),
            bytes(&sample(7, 7, 5)),
            bytes(&sample_joints(9, 3, 6)),
            bytes(&sample_joints(16, 3, 7)),
        ];
        // One Boot reused for every pair, as a head that booted before would be.
        let mut reused = boot(&[], &[]);
        for a in &contents {
            for b in &contents {
                let want = boot_by_value(a, b);
                assert_eq!(boot(a, b), want);
                reused.boot_in_place(a, b);
                assert_eq!(reused, want);
            }
        }
    }

    fn network(b: &Boot) -> &Network {
        match &b.estimator {
            Estimator::Network(n) => n,
            Estimator::Fallback(_) => panic!("fallback"),
        }
    }

    #[test]
    fn thesis_net_runs_on_the_fast_path_and_other_topologies_on_the_flat_one() {
        let got = boot(&bytes(&sample(5, 1, 1)), &[]);
        assert!(network(&got).fast);
        // A 4-7-3 and a 9-12-3 blob run too, through the blob's own inference.
        for (blob, inputs) in [(sample(7, 1, 4), 4), (sample_joints(12, 1, 5), 9)] {
            let got = boot(&bytes(&blob), &[]);
            assert_eq!(got.slot_a, SlotStatus::Valid { generation: 1 });
            let n = network(&got);
            assert!(!n.fast);
            assert_eq!(
                (n.model.inputs, n.model.hidden, n.model.outputs),
                (inputs, u16::from(blob.topology.hidden), 3)
            );
            let e = got.estimate(&P).unwrap();
            let mut x = std::vec::Vec::from(P.to_array());
            x.extend_from_slice(&Joints::HOME.0[..inputs as usize - 4]);
            let mut want = [0.0f32; 3];
            blob.infer(&x, &mut want).unwrap();
            assert_eq!([e.x, e.y, e.z].map(f32::to_bits), want.map(f32::to_bits));
            assert_eq!(e.in_range, blob.in_range(&x));
        }
    }

    #[test]
    fn posture_aware_net_is_fed_the_current_setpoints() {
        // The thesis family, and the default family with its points in the eye platform's
        // and in the cyclopean frame (turned into the head frame by the joints the head feeds).
        let framed = |frame| {
            SampleSpec::THESIS
                .inputs(InputKind::StereoJoints)
                .hidden(9)
                .generation(3)
                .seed(11)
                .family(blob::Family::INVERSE_DEPTH_SKIP)
                .frame(frame)
                .build()
        };
        let (platform, cyclopean) =
            (framed(blob::OutputFrame::EyePlatform), framed(blob::OutputFrame::Cyclopean));
        for blob in [sample_joints(9, 3, 11), platform, cyclopean] {
            fed_the_current_setpoints(&blob);
        }
    }

    fn fed_the_current_setpoints(blob: &ModelBlob) {
        let mut h = head(boot(&bytes(blob), &[]));
        let infer = |joints: &Joints| {
            let mut x = std::vec::Vec::from(P.to_array());
            x.extend_from_slice(&joints.0);
            let mut y = [0.0f32; 3];
            blob.infer(&x, &mut y).unwrap();
            (y, blob.in_range(&x))
        };
        let at_home = h.estimate(&P).unwrap();
        assert_eq!(h.joints(), Joints::HOME);
        assert_eq!([at_home.x, at_home.y, at_home.z], infer(&Joints::HOME).0);
        // Look: the estimate comes from the posture before the move...
        let look = h.look(&P).unwrap();
        assert_eq!(look.estimate, at_home);
        // ...and once the head has moved, Estimate feeds the new setpoints.
        for _ in 0..200 {
            h.tick();
        }
        assert!(!h.controller.is_moving());
        assert_eq!(h.joints(), look.target);
        assert_ne!(look.target, Joints::HOME);
        let r = h.respond(&req(5, RequestBody::Estimate(P)), V);
        let ResponseBody::Estimate(e) = r.body else { panic!("{r:?}") };
        let (want, in_range) = infer(&look.target);
        assert_eq!([e.x, e.y, e.z].map(f32::to_bits), want.map(f32::to_bits));
        assert_eq!(e.in_range, in_range);
        assert_ne!([e.x, e.y, e.z], [at_home.x, at_home.y, at_home.z]);
        // Boot alone (no gaze controller) answers as at home.
        assert_eq!(h.boot.estimate(&P).unwrap(), at_home);
        // A posture frame: the net's point turned by the joints the head fed.
        if blob.frame != blob::OutputFrame::Head {
            let mut head_frame = blob.clone();
            head_frame.frame = blob::OutputFrame::Head;
            let mut x = std::vec::Vec::from(P.to_array());
            x.extend_from_slice(&look.target.0);
            let mut y = [0.0f32; 3];
            head_frame.infer(&x, &mut y).unwrap();
            let j = look.target.0;
            assert_ne!([j[0], j[1], j[2]], [0.0; 3]);
            let turned = match blob.frame {
                blob::OutputFrame::Cyclopean => gaze::cyclopean_to_base(j, y),
                _ => gaze::platform_to_base([j[0], j[1], j[2]], y),
            };
            assert_eq!([e.x, e.y, e.z].map(f32::to_bits), turned.map(f32::to_bits));
        }
    }

    #[test]
    fn network_estimate_matches_blob_inference_bit_for_bit() {
        let blob = sample(5, 1, 77);
        let got = boot(&bytes(&blob), &[]);
        for k in 0..200 {
            let p = StereoPoint {
                u_l: 290.0 + k as f32 * 0.37,
                v_l: 215.0 + k as f32 * 0.21,
                u_r: 270.0 + k as f32 * 0.33,
                v_r: 230.0 - k as f32 * 0.05,
            };
            let e = got.estimate(&p).unwrap();
            let mut want = [0.0f32; 3];
            blob.infer(&p.to_array(), &mut want).unwrap();
            assert_eq!([e.x.to_bits(), e.y.to_bits(), e.z.to_bits()], want.map(f32::to_bits));
            let in_range =
                blob.in_range(&p.to_array()) && outputs_in_range(&blob, &p.to_array(), &want);
            assert_eq!(e.in_range, in_range, "{p:?}");
            assert_eq!(e.source, Source::Network);
        }
    }

    #[test]
    fn inverse_depth_family_runs_on_both_paths_bit_for_bit() {
        // 4-5-3 (fast path) and 4-7-3 (flat path), outputs X/Z, Y/Z, 1/Z: o2 kept positive.
        for hidden in [5u8, 7] {
            let mut blob = sample(hidden, 1, 21);
            blob.family = blob::Family::INVERSE_DEPTH;
            blob.out_offset = heapless::Vec::from_slice(&[0.0, 0.0, 0.05]).unwrap();
            blob.out_scale = heapless::Vec::from_slice(&[0.02, 0.02, 0.001]).unwrap();
            let got = boot(&bytes(&blob), &[]);
            assert_eq!(network(&got).fast, hidden == 5);
            for k in 0..50 {
                let p = StereoPoint {
                    u_l: 300.0 + k as f32 * 0.7,
                    v_l: 225.0 + k as f32 * 0.3,
                    u_r: 285.0 + k as f32 * 0.6,
                    v_r: 235.0,
                };
                let e = got.estimate(&p).unwrap();
                let mut want = [0.0f32; 3];
                blob.infer(&p.to_array(), &mut want).unwrap();
                assert_eq!([e.x, e.y, e.z].map(f32::to_bits), want.map(f32::to_bits));
                assert!(e.z > 0.0 && (1.0 / e.z - 0.05).abs() < 0.01, "{e:?}");
            }
        }
    }

    #[test]
    fn estimates_far_outside_the_training_outputs_are_out_of_range() {
        let p = StereoPoint { u_l: 330.0, v_l: 240.0, u_r: 305.0, v_r: 240.0 };
        let good = sample(5, 1, 77);
        assert!(good.in_range(&p.to_array()));
        // A CRC-valid blob with a huge weight: x's output bias (w2[0][0..5], then b2[0]).
        let mut huge_bias = good.clone();
        huge_bias.params[25 + 5] = 1e37;
        // And one whose output offset itself was damaged: caught by PLAUSIBLE_CM.
        let mut huge_offset = good.clone();
        huge_offset.out_offset[0] = 3.4e38;
        for bad in [huge_bias, huge_offset] {
            let e = boot(&bytes(&bad), &[]).estimate(&p).unwrap();
            assert!(e.x.is_finite() && libm::fabsf(e.x) > 1e30, "{e:?}");
            assert!(!e.in_range, "{e:?}");
        }
        // The box: offset +- 4 scales; x has offset 0, scale 3.
        let y = |x: f32| [x, 0.0, 115.0];
        let x = p.to_array();
        assert!(outputs_in_range(&good, &x, &y(12.0)));
        assert!(outputs_in_range(&good, &x, &y(-12.0)));
        assert!(!outputs_in_range(&good, &x, &y(12.01)));
        assert!(!outputs_in_range(&good, &x, &y(f32::NAN)));
        assert!(!outputs_in_range(&good, &x, &[0.0, 0.0]));
        // A depth behind the cameras is out of range, even within the margin of a training
        // box in front of them.
        let z = |z: f32| [0.0, 0.0, z];
        let (off, scale) = (good.out_offset[2], libm::fabsf(good.out_scale[2]));
        assert!(off - scale > 0.0 && off - OUTPUT_MARGIN * scale < -1.0, "{off} {scale}");
        assert!(outputs_in_range(&good, &x, &z(1.0)));
        assert!(!outputs_in_range(&good, &x, &z(0.0)));
        assert!(!outputs_in_range(&good, &x, &z(-1.0)));
    }

    #[test]
    fn bad_points_are_errors_not_panics() {
        let net = boot(&bytes(&sample(5, 1, 3)), &[]);
        let fb = boot(&[], &[]);
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let p = StereoPoint { v_r: bad, ..P };
            assert_eq!(net.estimate(&p), Err(ErrorCode::NonFinite));
            assert_eq!(fb.estimate(&p), Err(ErrorCode::NonFinite));
        }
        // Zero and negative disparity have no traditional depth.
        let p = StereoPoint { u_r: P.u_l, ..P };
        assert_eq!(fb.estimate(&p), Err(ErrorCode::NoSolution));
        // Huge inputs: the network still answers (sigmoids saturate), out of range.
        let p = StereoPoint { u_l: 3e38, v_l: -3e38, u_r: 1e30, v_r: 0.0 };
        let e = net.estimate(&p).unwrap();
        assert!(!e.in_range);
        assert!(e.x.is_finite() && e.z.is_finite());
    }

    fn head(boot: Boot) -> Head {
        Head::new(boot, GazeConfig::DEFAULT, &ControllerConfig::DEFAULT).unwrap()
    }

    fn req(id: u32, body: RequestBody) -> Request {
        Request { id, body }
    }

    const V: FirmwareVersion = FirmwareVersion { major: 1, minor: 2, patch: 3 };

    #[test]
    fn look_moves_the_setpoints_to_the_announced_target_within_limits() {
        let mut h = head(boot(&[], &[]));
        // A point to the left and below, about 1 m away.
        let p = StereoPoint { u_l: 250.0, v_l: 300.0, u_r: 220.0, v_r: 300.0 };
        let r = h.respond(&req(7, RequestBody::Look(p)), V);
        assert_eq!(r.id, 7);
        let ResponseBody::Look(l) = r.body else { panic!("{r:?}") };
        assert_eq!(l.estimate, h.boot.estimate(&p).unwrap());
        let limits = GazeConfig::DEFAULT.limits;
        assert!(limits.contains(&l.target));
        // Left of centre: positive pans; below: positive tilts (gaze sign convention).
        assert!(l.target.0[0] > 0.0 && l.target.0[3] > 0.0 && l.target.0[4] > 0.0);
        assert!(l.target.0[1] + l.target.0[2] > 0.0);
        // Vergence: the right eye turns in more than the left.
        assert!(l.target.0[4] > l.target.0[3]);
        let mut last = Joints::HOME;
        let max = h.controller.max_steps_per_tick();
        for _ in 0..200 {
            let sp = h.tick();
            assert!(limits.contains(&sp));
            for axis in Axis::ALL {
                let d = gaze::to_steps(sp[axis]) - gaze::to_steps(last[axis]);
                assert!(d.abs() <= max[axis.index()], "{axis:?} jumped {d} steps");
            }
            last = sp;
        }
        assert!(!h.controller.is_moving());
        assert_eq!(last, l.target);

        // Home brings every axis back to 0.
        let r = h.respond(&req(8, RequestBody::Home), V);
        assert_eq!(r.body, ResponseBody::Home);
        for _ in 0..200 {
            last = h.tick();
        }
        assert_eq!(last, Joints::HOME);
    }

    #[test]
    fn posture_moves_to_the_clamped_goal_and_state_reports_the_clock() {
        let mut h = head(boot(&[], &[]));
        let limits = GazeConfig::DEFAULT.limits;
        let st = |h: &mut Head| match h.respond(&req(2, RequestBody::State), V).body {
            ResponseBody::State(s) => s,
            b => panic!("{b:?}"),
        };
        let s0 = st(&mut h);
        assert_eq!(
            (s0.joints, s0.goal, s0.ticks, s0.moving),
            (Joints::HOME, Joints::HOME, 0, false)
        );
        // Far beyond the limits, off the grid, one joint NaN (keeps its goal: home).
        let asked = Joints([500.0, -500.0, f32::NAN, 1.0, -1.0]);
        let ResponseBody::State(s) = h.respond(&req(3, RequestBody::Posture(asked)), V).body else {
            panic!("posture refused")
        };
        assert!(limits.contains(&s.goal) && s.moving && s.ticks == 0);
        assert_eq!(s.goal, Joints(s.goal.0.map(gaze::quantize)));
        let (lo, hi) = (limits.step_range(Axis::NeckPan).1, limits.step_range(Axis::NeckTilt).0);
        assert_eq!((s.goal.0[0], s.goal.0[1]), (gaze::from_steps(lo), gaze::from_steps(hi)));
        assert_eq!(s.goal.0[2], 0.0);
        assert_eq!((s.goal.0[3], s.goal.0[4]), (gaze::quantize(1.0), gaze::quantize(-1.0)));
        for _ in 0..1000 {
            assert!(limits.contains(&h.tick()));
        }
        let s = st(&mut h);
        assert_eq!((s.joints, s.ticks, s.moving), (s.goal, 1000, false));
        // An infinite joint: refused, nothing moves.
        let inf = Joints([0.0, f32::INFINITY, 0.0, 0.0, 0.0]);
        let r = h.respond(&req(4, RequestBody::Posture(inf)), V);
        assert_eq!(r.body, ResponseBody::Error(ErrorCode::NonFinite));
        assert_eq!(st(&mut h).goal, s.goal);
        // Before the head is built (boot only): unsupported.
        let b = boot(&[], &[]);
        for body in [RequestBody::Posture(Joints::HOME), RequestBody::State] {
            let r = b.respond(&req(5, body), V);
            assert_eq!(r.body, ResponseBody::Error(ErrorCode::Unsupported));
        }
        // A posture arms the loop; a state query or a refused posture does not.
        for (body, arms) in [
            (RequestBody::State, false),
            (RequestBody::Posture(inf), false),
            (RequestBody::Posture(Joints::HOME), true),
        ] {
            let mut ml = MainLoop::new();
            let mut buf = [0u8; protocol::MAX_FRAME_LEN];
            let n = protocol::encode_request(&req(6, body), &mut buf).unwrap().len();
            ml.frame(Ok(&mut buf[..n - 1]), |r| h.respond(r, V));
            assert_eq!(ml.armed(), arms, "{body:?}");
        }
    }

    #[test]
    fn bad_looks_are_refused_without_moving() {
        let mut h = head(boot(&[], &[]));
        let nan = StereoPoint { u_l: f32::NAN, ..P };
        let behind = StereoPoint { u_r: P.u_l + 1.0, ..P };
        let too_close = StereoPoint { u_l: 620.0, u_r: 20.0, ..P };
        for (p, code) in [
            (nan, ErrorCode::NonFinite),
            (behind, ErrorCode::NoSolution),
            (too_close, ErrorCode::Unreachable),
        ] {
            let r = h.respond(&req(3, RequestBody::Look(p)), V);
            assert_eq!(r.body, ResponseBody::Error(code), "{p:?}");
            assert!(!h.controller.is_moving());
            assert_eq!(h.tick(), Joints::HOME);
        }
    }

    #[test]
    fn respond_answers_every_request_with_its_id() {
        let mut h = head(boot(&bytes(&sample(5, 4, 1)), &[]));
        let info = h.respond(&req(11, RequestBody::Info), V);
        let ResponseBody::Info(i) = info.body else { panic!("{info:?}") };
        assert_eq!((info.id, i.firmware, i.generation), (11, V, 4));
        assert_eq!(h.respond(&req(12, RequestBody::Ping), V).body, ResponseBody::Pong);
        let e = h.respond(&req(13, RequestBody::Estimate(P)), V);
        assert_eq!(e.body, ResponseBody::Estimate(h.boot.estimate(&P).unwrap()));
        let b = h.respond(&req(14, RequestBody::Bench { point: P, count: 1 }), V);
        assert_eq!(b.body, ResponseBody::Error(ErrorCode::Unsupported));
    }

    #[test]
    fn read_frame_maps_frame_errors_to_unsolicited_replies() {
        let malformed = Err(frame_error(ErrorCode::Malformed));
        assert_eq!(
            read_frame(Err(protocol::ProtocolError::Oversize)),
            Err(frame_error(ErrorCode::Oversize))
        );
        assert_eq!(read_frame(Ok(&mut [0x03, 0x07])), malformed);
        assert_eq!(read_frame(Ok(&mut [])), malformed);
        let want = req(5, RequestBody::Look(P));
        let mut buf = [0u8; protocol::MAX_FRAME_LEN];
        let n = protocol::encode_request(&want, &mut buf).unwrap().len();
        // As the accumulator hands it out: without the sentinel.
        assert_eq!(read_frame(Ok(&mut buf[..n - 1])), Ok(want));
        assert_eq!(frame_error(ErrorCode::Malformed).id, protocol::UNSOLICITED_ID);
    }

    #[test]
    fn main_loop_commands_nothing_until_a_look_or_home_is_answered() {
        let mut h = head(boot(&[], &[]));
        let mut l = MainLoop::new();
        let encoded = |r: &Request| {
            let mut buf = [0u8; protocol::MAX_FRAME_LEN];
            let n = protocol::encode_request(r, &mut buf).unwrap().len();
            (buf, n - 1)
        };
        // Ticks before any request, an Info, a bad frame and a failed Look: not armed.
        assert!(!l.tick(&mut h).command);
        let (mut b, n) = encoded(&req(1, RequestBody::Info));
        let r = l.frame(Ok(&mut b[..n]), |q| h.respond(q, V));
        assert_eq!(r.id, 1);
        assert_eq!(
            l.frame(Ok(&mut [0x03, 0x07]), |_| unreachable!()),
            frame_error(ErrorCode::Malformed)
        );
        let nan = StereoPoint { u_l: f32::NAN, ..P };
        let (mut b, n) = encoded(&req(2, RequestBody::Look(nan)));
        let r = l.frame(Ok(&mut b[..n]), |q| h.respond(q, V));
        assert!(matches!(r.body, ResponseBody::Error(_)), "{r:?}");
        assert!(!l.armed() && !l.tick(&mut h).command);
        // A Look answered arms it; the tick's setpoint is the head's.
        let (mut b, n) = encoded(&req(3, RequestBody::Look(P)));
        let r = l.frame(Ok(&mut b[..n]), |q| h.respond(q, V));
        assert!(matches!(r.body, ResponseBody::Look(_)), "{r:?}");
        assert!(l.armed());
        let mut twin = h.clone();
        let t = l.tick(&mut h);
        assert!(t.command);
        assert_eq!(t.setpoint, twin.tick());
        // So does a Home, from a fresh loop.
        let mut l = MainLoop::new();
        let (mut b, n) = encoded(&req(4, RequestBody::Home));
        l.frame(Ok(&mut b[..n]), |q| h.respond(q, V));
        assert!(l.armed());
    }

    /// Any f32 a wire or a bad sensor could give: non-finite, huge, zero, in the image, any bits.
    pub(crate) fn any_f32() -> impl proptest::strategy::Strategy<Value = f32> {
        use proptest::prelude::*;
        prop_oneof![
            Just(f32::NAN),
            Just(f32::INFINITY),
            Just(f32::NEG_INFINITY),
            Just(f32::MAX),
            Just(-f32::MAX),
            Just(0.0f32),
            -1e6f32..1e6f32,
            0.0f32..640.0,
            proptest::num::f32::ANY,
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Whatever arrives (NaN, infinities, huge and negative values, any order, any
        /// timing), every setpoint stays within the joint limits and moves at most the per-tick
        /// step limit, and every request is answered with its id.
        #[test]
        fn any_requests_keep_setpoints_within_limits(
            reqs in proptest::collection::vec(
                (0u8..4, any_f32(), any_f32(), any_f32(), any_f32(), 0u32..40),
                1..12,
            ),
            network in 0u8..3,
        ) {
            let a = match network {
                0 => StdVec::new(),
                1 => bytes(&sample(5, 1, 5)),
                _ => bytes(&sample_joints(8, 1, 5)),
            };
            let mut h = head(boot(&a, &[]));
            let limits = GazeConfig::DEFAULT.limits;
            let max = h.controller.max_steps_per_tick();
            let mut last = h.controller.setpoint_steps();
            for (k, (kind, u_l, v_l, u_r, v_r, ticks)) in reqs.into_iter().enumerate() {
                let p = StereoPoint { u_l, v_l, u_r, v_r };
                let body = match kind {
                    0 => RequestBody::Look(p),
                    1 => RequestBody::Estimate(p),
                    2 => RequestBody::Home,
                    _ => RequestBody::Info,
                };
                let r = h.respond(&req(k as u32 + 1, body), V);
                proptest::prop_assert_eq!(r.id, k as u32 + 1);
                for _ in 0..ticks {
                    let sp = h.tick();
                    proptest::prop_assert!(limits.contains(&sp), "{:?}", sp);
                    let steps = h.controller.setpoint_steps();
                    for i in 0..5 {
                        proptest::prop_assert!((steps[i] - last[i]).abs() <= max[i]);
                    }
                    last = steps;
                }
            }
        }
    }

    #[test]
    fn classifies_raw_slot_bytes() {
        assert_eq!(slot_state(&[0xFF; 64]), SlotState::Empty);
        assert_eq!(slot_state(&[0x00; 64]), SlotState::Empty);
        assert_eq!(
            slot_state(b"HVSW\x01\x00\x10\x00\x00\x00"),
            SlotState::Invalid(crate::runtime::blob::BlobError::Truncated)
        );
    }
}
