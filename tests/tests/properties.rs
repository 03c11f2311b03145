//! Property tests of the head on the wire: whatever bytes and requests arrive (NaN, infinities,
//! huge and negative coordinates, garbage, truncated and overlong frames, any timing), every
//! setpoint and every MCDC/PWM command stays within the joint limits and the per-tick rate
//! limits, and the head keeps answering.
//!
//! `hvs-shared`'s own property test (`head::tests::any_requests_keep_setpoints_within_limits`)
//! calls `Head::respond` directly with the default settings; these go through the firmware's
//! receive path (`hvs_tests::sim::SimHead`: `FrameAccumulator`, `head::read_frame`), check the
//! servo wire formats too, and vary the gaze, controller and drive settings.

use hvs_shared::runtime::gaze::{self, AxisLimits, GazeConfig, HeadGeometry, JointLimits, Joints};
use hvs_shared::runtime::head;
use hvs_shared::runtime::protocol::{
    self, ErrorCode, Request, RequestBody, Response, ResponseBody, StereoPoint, MAX_FRAME_LEN,
    UNSOLICITED_ID,
};
use hvs_shared::runtime::servo::{McdcAxis, McdcConfig};
use hvs_shared::runtime::trajectory::ControllerConfig;
use hvs_tests::sim::SimHead;
use proptest::prelude::*;

/// Floats as they might arrive: specials, extremes, plausible pixels, anything.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        1 => Just(f32::NAN),
        1 => Just(-f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(f32::MAX),
        1 => Just(f32::MIN),
        1 => Just(f32::MIN_POSITIVE),
        1 => Just(-0.0f32),
        1 => -1e6f32..1e6f32,
        3 => 0.0f32..640.0,
        1 => proptest::num::f32::ANY,
    ]
}

fn any_point() -> impl Strategy<Value = StereoPoint> {
    (any_f32(), any_f32(), any_f32(), any_f32()).prop_map(|(u_l, v_l, u_r, v_r)| StereoPoint {
        u_l,
        v_l,
        u_r,
        v_r,
    })
}

/// A point the head can usually look at: in the image, positive disparity.
fn plausible_point() -> impl Strategy<Value = StereoPoint> {
    (40.0f32..600.0, 40.0f32..440.0, 1.0f32..150.0, -3.0f32..3.0)
        .prop_map(|(u, v, disp, dv)| StereoPoint { u_l: u, v_l: v, u_r: u - disp, v_r: v + dv })
}

fn any_body() -> impl Strategy<Value = RequestBody> {
    prop_oneof![
        3 => any_point().prop_map(RequestBody::Look),
        3 => plausible_point().prop_map(RequestBody::Look),
        2 => any_point().prop_map(RequestBody::Estimate),
        1 => Just(RequestBody::Home),
        1 => Just(RequestBody::Ping),
        1 => Just(RequestBody::Info),
        1 => (any_point(), any::<u32>()).prop_map(|(point, count)| RequestBody::Bench { point, count }),
        3 => (any_f32(), any_f32(), any_f32(), any_f32(), any_f32())
            .prop_map(|(a, b, c, d, e)| RequestBody::Posture(Joints([a, b, c, d, e]))),
        1 => Just(RequestBody::State),
    ]
}

/// One thing happening on the link.
#[derive(Debug, Clone)]
enum Event {
    /// A well-formed request (after a `0x00` that ends any partial frame).
    Request(RequestBody),
    /// Arbitrary bytes, zeros included.
    Garbage(Vec<u8>),
    /// The first `cut` bytes of a request frame, then `0x00`.
    Truncated(RequestBody, usize),
    /// `len` non-zero bytes, more than the receive buffer holds (`MAX_FRAME_LEN` bytes before
    /// the sentinel), then `0x00`.
    Oversize(usize),
    /// Control ticks.
    Ticks(u32),
}

fn any_event() -> impl Strategy<Value = Event> {
    prop_oneof![
        4 => any_body().prop_map(Event::Request),
        1 => proptest::collection::vec(any::<u8>(), 0..200).prop_map(Event::Garbage),
        1 => (any_body(), 0usize..30).prop_map(|(b, c)| Event::Truncated(b, c)),
        1 => (MAX_FRAME_LEN + 1..700).prop_map(Event::Oversize),
        3 => (0u32..120).prop_map(Event::Ticks),
    ]
}

fn frame(req: &Request) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    protocol::encode_request(req, &mut buf).unwrap().to_vec()
}

/// What a body may be answered with.
fn answer_fits(body: &RequestBody, resp: &ResponseBody, limits: &JointLimits) -> bool {
    match (body, resp) {
        (RequestBody::Ping, ResponseBody::Pong) | (RequestBody::Home, ResponseBody::Home) => true,
        (RequestBody::Info, ResponseBody::Info(_)) => true,
        (RequestBody::Estimate(_), ResponseBody::Estimate(e)) => {
            e.x.is_finite() && e.y.is_finite() && e.z.is_finite()
        }
        (RequestBody::Look(_), ResponseBody::Look(l)) => {
            limits.contains(&l.target) && l.target == Joints(l.target.0.map(gaze::quantize))
        }
        (RequestBody::Estimate(_), ResponseBody::Error(c)) => {
            matches!(c, ErrorCode::NonFinite | ErrorCode::NoSolution)
        }
        (RequestBody::Look(_), ResponseBody::Error(c)) => {
            matches!(c, ErrorCode::NonFinite | ErrorCode::NoSolution | ErrorCode::Unreachable)
        }
        (RequestBody::Bench { .. }, ResponseBody::Error(ErrorCode::Unsupported)) => true,
        (RequestBody::Posture(j), ResponseBody::State(s)) => {
            // Accepted only when no joint is infinite; the goal within the limits, on the grid.
            !j.0.iter().any(|a| a.is_infinite())
                && limits.contains(&s.goal)
                && s.goal == Joints(s.goal.0.map(gaze::quantize))
                && limits.contains(&s.joints)
        }
        (RequestBody::Posture(j), ResponseBody::Error(ErrorCode::NonFinite)) => {
            j.0.iter().any(|a| a.is_infinite())
        }
        (RequestBody::State, ResponseBody::State(s)) => limits.contains(&s.joints),
        _ => false,
    }
}

fn model_slot() -> Vec<u8> {
    let mut b = hvs_tests::blob_bytes(&hvs_tests::sample_model(2, 42));
    b.resize(hvs_shared::runtime::blob::MAX_BLOB_LEN, 0xFF);
    b
}

fn run_events(head: &mut SimHead, events: &[Event]) -> Result<(), TestCaseError> {
    let limits = head.head.gaze.limits;
    let mut id = 1u32;
    for ev in events {
        match ev {
            Event::Request(body) => {
                let mut bytes = vec![0u8];
                bytes.extend(frame(&Request { id, body: *body }));
                let got = head.feed(&bytes).map_err(|v| TestCaseError::fail(v.0))?;
                let last = got.last().copied();
                let Some(Response { id: rid, body: resp }) = last else {
                    return Err(TestCaseError::fail(format!("request {id} unanswered")));
                };
                prop_assert_eq!(rid, id);
                prop_assert!(answer_fits(body, &resp, &limits), "{:?} -> {:?}", body, resp);
                // Anything before the answer came from an unfinished frame: an error.
                for r in &got[..got.len() - 1] {
                    prop_assert_eq!(r.id, UNSOLICITED_ID);
                }
                id += 1;
            }
            Event::Garbage(g) => {
                let got = head.feed(g).map_err(|v| TestCaseError::fail(v.0))?;
                // Garbage can hold a well-formed request; whatever it is, it gets an answer
                // that fits (checked by feed: ids, frame size), and nothing unasked moves.
                let _ = got;
            }
            Event::Truncated(body, cut) => {
                let f = frame(&Request { id, body: *body });
                let mut bytes = vec![0u8];
                bytes.extend_from_slice(&f[..(*cut).min(f.len() - 1)]);
                bytes.push(0);
                head.feed(&bytes).map_err(|v| TestCaseError::fail(v.0))?;
            }
            Event::Oversize(len) => {
                let mut bytes = vec![0u8];
                bytes.extend((0..*len).map(|i| (i % 255 + 1) as u8));
                bytes.push(0);
                let got = head.feed(&bytes).map_err(|v| TestCaseError::fail(v.0))?;
                prop_assert_eq!(got.last().copied(), Some(head::frame_error(ErrorCode::Oversize)));
            }
            Event::Ticks(n) => head.tick(*n).map_err(|v| TestCaseError::fail(v.0))?,
        }
    }
    head.settle(2000).map_err(|v| TestCaseError::fail(v.0))?;
    head.still_answers(u32::MAX).map_err(|v| TestCaseError::fail(v.0))?;
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Default settings, network or fallback: any mix of requests, garbage, truncated and
    /// overlong frames and ticks keeps every setpoint and servo command within the limits,
    /// every request is answered with its id and a fitting answer, and the head answers after.
    #[test]
    fn wire_streams_keep_the_head_within_limits_and_answering(
        events in proptest::collection::vec(any_event(), 1..40),
        network in any::<bool>(),
    ) {
        let slot = if network { model_slot() } else { Vec::new() };
        let mut head = SimHead::boot(&slot, &[]);
        run_events(&mut head, &events)?;
    }
}

fn any_limits() -> impl Strategy<Value = JointLimits> {
    // Speeds of at least one 0.18° step per 100 Hz tick (the controller refuses less).
    let axis = (-120.0f32..=0.0, 0.0f32..=120.0, 18.5f32..1000.0)
        .prop_map(|(lo, hi, v)| AxisLimits { min_deg: lo, max_deg: hi, max_vel_deg_s: v });
    [axis.clone(), axis.clone(), axis.clone(), axis.clone(), axis].prop_map(JointLimits)
}

fn any_mcdc() -> impl Strategy<Value = McdcConfig> {
    let axis = (any::<u8>(), prop_oneof![1.0f32..200.0, -200.0f32..-1.0], -1_000_000i32..1_000_000)
        .prop_map(|(node, counts_per_deg, zero_counts)| McdcAxis {
            node,
            counts_per_deg,
            zero_counts,
        });
    [axis.clone(), axis.clone(), axis.clone(), axis.clone(), axis].prop_map(McdcConfig)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Any joint limits, neck/eye split (NaN, negative, above 1), head geometry, distance
    /// bounds, move durations and MCDC drive settings: every setpoint and command stays within
    /// the configured limits, and after each `Look` the head comes to rest exactly on the
    /// target it announced.
    #[test]
    fn any_settings_keep_setpoints_within_their_limits(
        limits in any_limits(),
        neck_share in any_f32(),
        half_baseline in prop_oneof![Just(hvs_shared::runtime::gaze::HALF_BASELINE_CM as f32), any_f32()],
        neck_centre in [-20.0f32..20.0, -20.0f32..20.0, -20.0f32..20.0],
        min_distance in prop_oneof![Just(10.0f32), any_f32()],
        max_distance in prop_oneof![Just(100_000.0f32), any_f32()],
        neck_time in 0.05f32..3.0,
        eye_time in 0.02f32..1.0,
        mcdc in any_mcdc(),
        looks in proptest::collection::vec(prop_oneof![plausible_point(), any_point()], 1..8),
        network in any::<bool>(),
    ) {
        let gaze = GazeConfig {
            geometry: HeadGeometry { half_baseline_cm: half_baseline, neck_centre_cm: neck_centre },
            neck_share,
            min_distance_cm: min_distance,
            max_distance_cm: max_distance,
            limits,
        };
        let control = ControllerConfig { limits, neck_time_s: neck_time, eye_time_s: eye_time, control_hz: 100 };
        let slot = if network { model_slot() } else { Vec::new() };
        let mut head = SimHead::new(head::boot(&slot, &[]), gaze, &control).unwrap();
        head.mcdc = mcdc;
        for (k, p) in looks.iter().enumerate() {
            let id = k as u32 + 1;
            let got = head.request(&Request { id, body: RequestBody::Look(*p) })
                .map_err(|v| TestCaseError::fail(v.0))?;
            let last = got.last().copied().map(|r| r.body);
            match last {
                Some(ResponseBody::Look(l)) => {
                    prop_assert!(limits.contains(&l.target), "{:?}", l.target);
                    head.settle(5000).map_err(|v| TestCaseError::fail(v.0))?;
                    prop_assert_eq!(head.head.controller.setpoint(), l.target);
                }
                Some(ResponseBody::Error(_)) => head.tick(50).map_err(|v| TestCaseError::fail(v.0))?,
                other => prop_assert!(false, "Look answered with {:?}", other),
            }
        }
        head.still_answers(u32::MAX).map_err(|v| TestCaseError::fail(v.0))?;
    }
}
