//! The head firmware in QEMU (`netduinoplus2`) against the host: bit-for-bit estimates, slot
//! choice with corrupted slots, fallback, bad frames, the MCDC commands of a Look sequence, and
//! `hvs image` images (raw binary and Intel HEX) booting at the addresses they name.
//!
//! These tests need `qemu-system-arm` and the firmware ELF
//! (`cargo build --profile firmware -p hvs-firmware --target thumbv7em-none-eabihf --features qemu`).
//! They are `#[ignore]`d in a plain `cargo test` and run by `.ci/run` with
//! `cargo test -p hvs-tests --test qemu -- --ignored`; when run, a missing QEMU or ELF is a
//! failure with the command that fixes it, never a skip.

use hvs_host::device::link::{Endpoint, Link};
use hvs_host::device::qemu::{find_firmware, free_port, Emulator, EmulatorConfig, FIRMWARE_BUILD};
use hvs_shared::runtime::blob::{self, BlobError, ModelBlob, MAX_BLOB_LEN};
use hvs_shared::runtime::gaze::{self, Axis, GazeConfig, Joints};
use hvs_shared::runtime::head::{self, Head};
use hvs_shared::runtime::protocol::{
    self, ErrorCode, Mode, Request, RequestBody, Response, ResponseBody, Slot, SlotStatus, Source,
    StereoPoint, MAX_FRAME_LEN, UNSOLICITED_ID,
};
use hvs_shared::runtime::servo::{parse_mcdc, McdcCmd, McdcConfig};
use hvs_shared::runtime::traditional::{traditional_xyz, Calibration};
use hvs_shared::runtime::trajectory::ControllerConfig;
use hvs_tests::{sample_model as model, workspace_root};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A QEMU run with its files in a fresh temporary directory.
struct Run {
    emu: Emulator,
    link: Link,
    dir: PathBuf,
}

impl Run {
    fn servo_log(&self) -> PathBuf {
        self.dir.join("servo.log")
    }
}

impl Drop for Run {
    fn drop(&mut self) {
        self.emu.kill();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn require_qemu() {
    let ok = std::process::Command::new("qemu-system-arm")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "qemu-system-arm is not installed: apt-get install -y qemu-system-arm (CI={})",
        std::env::var("CI").unwrap_or_default()
    );
}

fn firmware() -> PathBuf {
    let fw = find_firmware(None);
    assert!(
        fw.is_file(),
        "{}: firmware ELF missing; build it first: {FIRMWARE_BUILD}",
        fw.display()
    );
    fw
}

/// Boots the firmware with these slot contents and waits until it answers.
fn boot(name: &str, slot_a: Option<&[u8]>, slot_b: Option<&[u8]>) -> Run {
    boot_with(name, slot_a, slot_b, vec![])
}

/// [`boot`] with both slots filled: the head's `Info`, after checking that its estimates
/// (from `source`) equal those of the host's head booted from the same slots.
fn boot_slots(
    name: &str,
    slot_a: &[u8],
    slot_b: &[u8],
    source: Source,
) -> (Run, protocol::InfoData) {
    let mut run = boot(name, Some(slot_a), Some(slot_b));
    let i = info(&mut run);
    assert_estimates_match(&mut run, &head::boot(slot_a, slot_b), source);
    (run, i)
}

/// [`boot`] with extra QEMU arguments (e.g. more `-device loader` images).
fn boot_with(name: &str, slot_a: Option<&[u8]>, slot_b: Option<&[u8]>, extra: Vec<String>) -> Run {
    require_qemu();
    let dir = std::env::temp_dir().join(format!("hvs-qemu-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let write = |file: &str, bytes: Option<&[u8]>| {
        bytes.map(|b| {
            let p = dir.join(file);
            std::fs::write(&p, b).unwrap();
            p
        })
    };
    let port = free_port().unwrap();
    let cfg = EmulatorConfig {
        firmware: firmware(),
        slot_a: write("a.bin", slot_a),
        slot_b: write("b.bin", slot_b),
        listen: format!("127.0.0.1:{port}"),
        servo_log: dir.join("servo.log"),
        qemu: "qemu-system-arm".into(),
        extra,
    };
    let emu = Emulator::start(&cfg).unwrap();
    let endpoint: Endpoint = emu.endpoint.parse().unwrap();
    let mut link = Link::open(&endpoint, Duration::from_secs(10)).unwrap();
    link.timeout = Duration::from_secs(5);
    link.wait_ready(Duration::from_secs(20)).unwrap();
    Run { emu, link, dir }
}

fn encode(b: &ModelBlob) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_BLOB_LEN];
    let n = b.encode(&mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// The blob with one payload bit flipped (its CRC then fails).
fn corrupted(b: &ModelBlob) -> Vec<u8> {
    let mut bytes = encode(b);
    bytes[blob::HEADER_LEN + 7] ^= 0x04;
    assert_eq!(blob::decode(&bytes), Err(BlobError::BadCrc));
    bytes
}

/// A few hundred points: every fixture row of the four thesis cases plus seeded points in and
/// around the image, some far outside the training box.
fn points() -> Vec<StereoPoint> {
    let mut pts = Vec::new();
    let dir = workspace_root().join("shared/tests/fixtures");
    for case in 1..=4 {
        for set in ["train", "test"] {
            let path = dir.join(format!("case{case}_{set}.csv"));
            let text = std::fs::read_to_string(&path).unwrap();
            for line in text.lines().skip(1) {
                let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
                pts.push(StereoPoint {
                    u_l: f[0] as f32,
                    v_l: f[1] as f32,
                    u_r: f[2] as f32,
                    v_r: f[3] as f32,
                });
            }
        }
    }
    let mut s: u32 = 0x9e37_79b9;
    let mut rnd = |lo: f32, hi: f32| {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        lo + (s as f32 / u32::MAX as f32) * (hi - lo)
    };
    for _ in 0..100 {
        let u_r = rnd(0.0, 600.0);
        pts.push(StereoPoint {
            u_l: u_r + rnd(1.0, 120.0),
            v_l: rnd(0.0, 480.0),
            u_r,
            v_r: rnd(0.0, 480.0),
        });
    }
    assert!(pts.len() >= 300, "{}", pts.len());
    pts
}

/// The stereo point `[u_l, v_l, u_r, v_r]`.
fn point(px: [f32; 4]) -> StereoPoint {
    StereoPoint { u_l: px[0], v_l: px[1], u_r: px[2], v_r: px[3] }
}

/// The head's estimate of `p` (panics if it answers anything else).
fn estimate(run: &mut Run, p: StereoPoint) -> protocol::EstimateData {
    match run.link.request(RequestBody::Estimate(p)).unwrap() {
        ResponseBody::Estimate(e) => e,
        other => panic!("Estimate of {p:?} answered {other:?}"),
    }
}

/// Asserts that the head runs a network from `slot` at `generation`.
#[track_caller]
fn assert_network(i: &protocol::InfoData, slot: Slot, generation: u32) {
    assert_eq!((i.mode, i.slot, i.generation), (Mode::Network, Some(slot), generation));
}

fn info(run: &mut Run) -> protocol::InfoData {
    match run.link.request(RequestBody::Info).unwrap() {
        ResponseBody::Info(i) => i,
        other => panic!("Info answered {other:?}"),
    }
}

/// Every point through the head equals the host's answer for the same boot, bit for bit.
fn assert_estimates_match(run: &mut Run, host: &head::Boot, expect_source: Source) {
    for p in points() {
        let got = run.link.request(RequestBody::Estimate(p)).unwrap();
        match (got, host.estimate(&p)) {
            (ResponseBody::Estimate(e), Ok(h)) => {
                assert_eq!(
                    [e.x.to_bits(), e.y.to_bits(), e.z.to_bits()],
                    [h.x.to_bits(), h.y.to_bits(), h.z.to_bits()],
                    "{p:?}: head {e:?} host {h:?}"
                );
                assert_eq!((e.source, e.in_range), (h.source, h.in_range), "{p:?}");
                assert_eq!(e.source, expect_source);
            }
            (ResponseBody::Error(c), Err(h)) => assert_eq!(c, h, "{p:?}"),
            (got, want) => panic!("{p:?}: head {got:?}, host {want:?}"),
        }
    }
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn estimates_equal_host_inference_bit_for_bit() {
    let m = model(1, 42);
    let bytes = encode(&m);
    let mut run = boot("bits", Some(&bytes), None);
    let i = info(&mut run);
    assert_network(&i, Slot::A, 1);
    assert_eq!(i.slot_a, SlotStatus::Valid { generation: 1 });
    assert_eq!(i.slot_b, SlotStatus::Empty);
    let model_info = i.model.expect("model metadata");
    assert_eq!(
        (model_info.hidden, model_info.seed, model_info.train_hash),
        (5, 42, 0x1234_5678_9abc_def0)
    );
    let peak = i.stack_peak.expect("the firmware reports its stack peak");
    // Boot has run, so some of the painted stack is used; the budget is 16 KiB for static RAM
    // (about 3 KiB) and stack together (`firmware/measure.sh` checks the sum).
    assert!((256..=12 * 1024).contains(&peak), "stack peak {peak} B");
    let host = head::boot(&bytes, &[]);
    assert_estimates_match(&mut run, &host, Source::Network);
    // The same numbers as the blob's own inference on the host.
    let p = point([340.0, 240.0, 295.0, 240.0]);
    let mut want = [0f32; 3];
    m.infer(&p.to_array(), &mut want).unwrap();
    let e = estimate(&mut run, p);
    assert_eq!([e.x, e.y, e.z].map(f32::to_bits), want.map(f32::to_bits));
    assert!(e.in_range);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn corrupted_slot_a_boots_valid_slot_b() {
    let (_run, i) =
        boot_slots("slot-b", &corrupted(&model(9, 1)), &encode(&model(2, 2)), Source::Network);
    assert_network(&i, Slot::B, 2);
    assert_eq!(i.slot_a, SlotStatus::Invalid(BlobError::BadCrc));
    assert_eq!(i.model.map(|m| m.seed), Some(2));
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn both_slots_corrupted_fall_back_and_answer() {
    let (mut run, i) = boot_slots(
        "fallback",
        &corrupted(&model(3, 3)),
        &corrupted(&model(4, 4)),
        Source::Fallback,
    );
    assert_eq!((i.mode, i.slot, i.model), (Mode::Fallback, None, None));
    assert_eq!(i.fallback, Calibration::BUILT_IN);
    let p = point([335.0, 240.0, 289.0, 240.0]);
    let want = traditional_xyz(&Calibration::BUILT_IN, &p.to_array()).unwrap();
    let e = estimate(&mut run, p);
    assert_eq!([e.x, e.y, e.z], want);
}

/// Waits for the next frame with the unsolicited id (an error about an unreadable frame).
fn next_unsolicited(run: &mut Run, within: Duration) -> Option<Response> {
    let until = Instant::now() + within;
    while let Some(r) = run.link.recv_until(until).unwrap() {
        if r.id == UNSOLICITED_ID {
            return Some(r);
        }
    }
    None
}

fn ping_answered(run: &mut Run) {
    assert_eq!(run.link.request(RequestBody::Ping).unwrap(), ResponseBody::Pong);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn bad_frames_get_errors_and_the_next_frame_is_answered() {
    let mut run = boot("frames", None, None);
    let malformed = Some(ResponseBody::Error(ErrorCode::Malformed));

    // Garbage without a zero, longer than any frame, then the terminator: Oversize.
    let garbage: Vec<u8> = (0..3000u32).map(|i| (i * 7 % 255 + 1) as u8).collect();
    run.link.send_raw(&garbage).unwrap();
    run.link.send_raw(&[0]).unwrap();
    let r = next_unsolicited(&mut run, Duration::from_secs(5));
    assert_eq!(r.map(|r| r.body), Some(ResponseBody::Error(ErrorCode::Oversize)));
    ping_answered(&mut run);

    // A truncated request: Malformed.
    let mut buf = [0u8; MAX_FRAME_LEN];
    let req = Request { id: 77, body: RequestBody::Estimate(point([340.0, 240.0, 300.0, 240.0])) };
    let frame = protocol::encode_request(&req, &mut buf).unwrap().to_vec();
    run.link.send_raw(&frame[..frame.len() / 2]).unwrap();
    run.link.send_raw(&[0]).unwrap();
    let r = next_unsolicited(&mut run, Duration::from_secs(5));
    assert_eq!(r.map(|r| r.body), malformed);
    ping_answered(&mut run);

    // Valid COBS, unknown request variant: Malformed.
    let mut b2 = [0u8; 16];
    let f = protocol::encode(&(5u32, 99u8), &mut b2).unwrap().to_vec();
    run.link.send_raw(&f).unwrap();
    let r = next_unsolicited(&mut run, Duration::from_secs(5));
    assert_eq!(r.map(|r| r.body), malformed);

    // Seeded random bytes with zeros in them: every reply is an unsolicited error, and the
    // head still answers afterwards.
    let mut s: u32 = 12345;
    let noise: Vec<u8> = (0..2000)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            if s.is_multiple_of(17) {
                0
            } else {
                s as u8
            }
        })
        .collect();
    run.link.send_raw(&noise).unwrap();
    run.link.send_raw(&[0]).unwrap();
    ping_answered(&mut run);
    // A truncated frame glued to a valid one: one error, then the valid one is answered.
    let mut glued = frame[..frame.len() / 2].to_vec();
    glued.push(0);
    glued.extend_from_slice(&frame);
    run.link.send_raw(&glued).unwrap();
    let until = Instant::now() + Duration::from_secs(5);
    let mut got_answer = false;
    while let Some(r) = run.link.recv_until(until).unwrap() {
        if r.id == 77 {
            assert!(matches!(r.body, ResponseBody::Estimate(_)), "{r:?}");
            got_answer = true;
            break;
        }
    }
    assert!(got_answer, "the valid frame after a truncated one was not answered");
    // Unsolicited replies are all errors.
    assert!(run
        .link
        .unsolicited
        .iter()
        .all(|r| matches!(r.body, ResponseBody::Error(_) | ResponseBody::Ready { .. })));
}

/// Per-axis sequences of the `LA` counts in an MCDC log, checking that every line parses, every
/// `LA` is followed by `M` on the same node, and every node is one of the head's.
/// Every count the servo log commanded lies within the default joint limits' counts.
fn assert_within_limits(got: &[Vec<i32>; 5], cfg: &McdcConfig) {
    let limits = GazeConfig::DEFAULT.limits;
    for axis in Axis::ALL {
        let (lo, hi) = (
            cfg.counts(&limits, axis, f32::NEG_INFINITY),
            cfg.counts(&limits, axis, f32::INFINITY),
        );
        let g = &got[axis.index()];
        assert!(g.iter().all(|c| (lo..=hi).contains(c)), "{axis:?} outside [{lo}, {hi}]: {g:?}");
    }
}

fn mcdc_sequences(log: &Path, cfg: &McdcConfig) -> [Vec<i32>; 5] {
    let text = std::fs::read(log).unwrap();
    let mut seqs: [Vec<i32>; 5] = Default::default();
    let mut pending: Option<u8> = None;
    for line in text.split(|&b| b == b'\r').filter(|l| !l.is_empty()) {
        let (node, cmd) = parse_mcdc(line)
            .unwrap_or_else(|e| panic!("bad MCDC line {:?}: {e:?}", String::from_utf8_lossy(line)));
        let axis = cfg
            .0
            .iter()
            .position(|a| a.node == node)
            .unwrap_or_else(|| panic!("unknown node {node}"));
        match cmd {
            McdcCmd::LoadAbsolute(c) => {
                assert_eq!(pending, None, "LA without M before it");
                seqs[axis].push(c);
                pending = Some(node);
            }
            McdcCmd::Move => {
                assert_eq!(pending, Some(node), "M without its LA");
                pending = None;
            }
            other => panic!("unexpected command {other:?}"),
        }
    }
    assert_eq!(pending, None);
    seqs
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn look_sequence_commands_follow_the_trajectory_within_limits() {
    let mut run = boot("look", None, None);
    let looks = [
        point([250.0, 300.0, 220.0, 300.0]),
        point([420.0, 150.0, 380.0, 150.0]),
        // Far above (pixels beyond the image): past neck plus eye tilt, clamped at the limits.
        point([330.0, -6000.0, 300.0, -6000.0]),
    ];
    // The host runs the same Head from the same boot.
    let mut host =
        Head::new(head::boot(&[], &[]), GazeConfig::DEFAULT, &ControllerConfig::DEFAULT).unwrap();
    let cfg = McdcConfig::DEFAULT;
    let limits = GazeConfig::DEFAULT.limits;
    let mut want: [Vec<i32>; 5] = Default::default();
    let record = |sp: &Joints, want: &mut [Vec<i32>; 5]| {
        for axis in Axis::ALL {
            let c = cfg.counts(&limits, axis, sp[axis]);
            let w = &mut want[axis.index()];
            if w.last() != Some(&c) {
                w.push(c);
            }
        }
    };
    let mut limited = false;
    for (k, p) in looks.iter().enumerate() {
        let r = run.link.request(RequestBody::Look(*p)).unwrap();
        let ResponseBody::Look(l) = r else { panic!("Look {k} answered {r:?}") };
        let h = host.look(p).unwrap();
        assert_eq!(l, h, "Look {k}");
        limited |= l.limited;
        // Let the move finish (neck 0.7 s; QEMU's SysTick follows the host clock).
        std::thread::sleep(Duration::from_millis(1500));
        while host.controller.is_moving() {
            let sp = host.tick();
            record(&sp, &mut want);
        }
    }
    assert!(limited, "the last target should hit a joint limit");
    assert_eq!(run.link.request(RequestBody::Home).unwrap(), ResponseBody::Home);
    std::thread::sleep(Duration::from_millis(1500));
    host.controller.home();
    while host.controller.is_moving() {
        let sp = host.tick();
        record(&sp, &mut want);
    }
    run.emu.kill();
    let got = mcdc_sequences(&run.servo_log(), &cfg);
    assert_within_limits(&got, &cfg);
    for axis in Axis::ALL {
        let i = axis.index();
        assert_eq!(got[i], want[i], "{axis:?}: servo log vs host trajectory");
        assert_eq!(got[i].last(), Some(&0), "{axis:?} did not return home");
        assert!(got[i].len() > 3, "{axis:?} barely moved: {:?}", got[i]);
    }
    // And the per-tick rate limit holds between consecutive commands.
    let max = host.controller.max_steps_per_tick();
    for axis in Axis::ALL {
        let i = axis.index();
        for w in got[i].windows(2) {
            assert!((w[1] - w[0]).abs() <= max[i], "{axis:?} jumped {w:?}");
        }
    }
}

/// `Posture` (protocol 3): the head moves to the clamped goal and `State` reports where it
/// is and its clock; an infinite joint is refused; the servo log stays within the limits and
/// ends at the goal's counts.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn posture_moves_the_head_and_state_reports_it() {
    require_qemu();
    let mut run = boot("posture", None, None);
    let limits = GazeConfig::DEFAULT.limits;
    let state = |run: &mut Run| match run.link.request(RequestBody::State).unwrap() {
        ResponseBody::State(s) => s,
        r => panic!("State answered {r:?}"),
    };
    let s0 = state(&mut run);
    assert_eq!((s0.joints, s0.moving), (Joints::HOME, false));
    let asked = Joints([20.0, -90.0, 4.0, f32::NAN, -3.0]);
    let ResponseBody::State(s) = run.link.request(RequestBody::Posture(asked)).unwrap() else {
        panic!("posture refused")
    };
    // The host's head computes the same goal from the same request.
    let mut host =
        Head::new(head::boot(&[], &[]), GazeConfig::DEFAULT, &ControllerConfig::DEFAULT).unwrap();
    host.controller.start(&asked);
    assert_eq!(s.goal, host.goal());
    assert!(limits.contains(&s.goal) && s.moving);
    assert_eq!(s.goal.0[1], gaze::from_steps(limits.step_range(Axis::NeckTilt).0), "clamped");
    let inf = Joints([0.0, 0.0, f32::NEG_INFINITY, 0.0, 0.0]);
    assert_eq!(
        run.link.request(RequestBody::Posture(inf)).unwrap(),
        ResponseBody::Error(ErrorCode::NonFinite)
    );
    // The neck takes 0.7 s; QEMU's SysTick follows the host clock.
    std::thread::sleep(Duration::from_millis(1500));
    let s1 = state(&mut run);
    assert_eq!((s1.joints, s1.goal, s1.moving), (s.goal, s.goal, false));
    assert!(s1.ticks >= s.ticks + 100, "the head's clock ran: {} -> {}", s.ticks, s1.ticks);
    run.emu.kill();
    let cfg = McdcConfig::DEFAULT;
    let got = mcdc_sequences(&run.servo_log(), &cfg);
    assert_within_limits(&got, &cfg);
    for axis in Axis::ALL {
        let i = axis.index();
        assert_eq!(got[i].last(), Some(&cfg.counts(&limits, axis, s.goal[axis])), "{axis:?}");
    }
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn images_written_by_hvs_image_boot_at_the_address_they_name() {
    use hvs_host::cli::image::{
        run as run_image, Args as ImageArgs, FormatArg as ImageFormat, SlotArg,
    };
    let dir = std::env::temp_dir().join(format!("hvs-image-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let model_path = dir.join("m.hvsw");
    std::fs::write(&model_path, encode(&model(1, 11))).unwrap();
    // `hvs image` of the model for `slot` at `generation`; returns the file.
    let write_image = |slot: SlotArg, generation: u32, format: ImageFormat, ext: &str| {
        let out = dir.join(format!("{slot:?}.{ext}"));
        run_image(&ImageArgs {
            model: model_path.clone(),
            slot,
            generation: Some(generation),
            format,
            output: out.clone(),
        })
        .unwrap();
        out
    };
    // The booted head runs the model (seed 11) from `slot` at `generation`; the other slot's
    // status is `other` (a for A, b for B).
    let runs = |i: protocol::InfoData, slot: Slot, generation: u32, other: SlotStatus| {
        assert_network(&i, slot, generation);
        let other_slot = if slot == Slot::A { i.slot_b } else { i.slot_a };
        assert_eq!(other_slot, other);
        assert_eq!(i.model.map(|m| m.seed), Some(11));
    };
    let images: Vec<Vec<u8>> = [(SlotArg::A, 3), (SlotArg::B, 5)]
        .into_iter()
        .map(|(slot, generation)| {
            std::fs::read(write_image(slot, generation, ImageFormat::Bin, "bin")).unwrap()
        })
        .collect();
    let mut run = boot("image", Some(&images[0]), Some(&images[1]));
    runs(info(&mut run), Slot::B, 5, SlotStatus::Valid { generation: 3 });
    drop(run);

    // Intel HEX images carry their own addresses: QEMU's generic loader without `addr` loads
    // a .hex file at the addresses of its records. A (generation 7) now beats B (6).
    let mut loaders = Vec::new();
    for (slot, generation) in [(SlotArg::A, 7), (SlotArg::B, 6)] {
        let out = write_image(slot, generation, ImageFormat::Hex, "hex");
        assert!(std::fs::read_to_string(&out).unwrap().starts_with(":02000004080"));
        loaders.push("-device".to_string());
        loaders.push(format!("loader,file={}", out.display()));
    }
    let mut run = boot_with("image-hex", None, None, loaders);
    runs(info(&mut run), Slot::A, 7, SlotStatus::Valid { generation: 6 });
    drop(run);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A posture-aware 9-input model through the firmware: boot runs it, `Look` moves the eyes,
/// and the next estimate (of another point, seen from the new posture) is fed the head's new
/// setpoints: it equals the host's inference with the same joints bit for bit, differs from
/// what the home posture would give, and is right.
#[test]
#[ignore = "needs qemu-system-arm and the firmware ELF; run by .ci/run"]
fn posture_aware_model_look_moves_the_eyes_and_the_next_estimate_is_right() {
    use hvs_host::sim::posture::{self as sets, PostureOptions, Sampling};
    use hvs_host::sim::sets::{SetKind, SimOptions};
    use hvs_host::train::{train, TrainConfig};
    use hvs_shared::runtime::blob::InputKind;
    use hvs_shared::sim::posture::{HeadRig, PostureRange};

    // Case III on the head. A net for the neighbourhood of the postures this test visits
    // (small, so that it trains in seconds in a debug build): the board protocol at 16 random
    // postures of a narrow range and at home.
    let head_rig = HeadRig::new(hvs_shared::sim::presets::CASE_3);
    let range = PostureRange {
        neck_pan: [-8.0, 2.0],
        neck_tilt: [-5.0, 2.0],
        eye_tilt: [-5.0, 2.0],
        version: [-8.0, 2.0],
        vergence: [0.0, 9.0],
    };
    let mut postures = sets::postures(
        &PostureOptions {
            sampling: Sampling::Random,
            count: 16,
            range,
            ..PostureOptions::default()
        },
        3,
    )
    .unwrap();
    postures.push(Joints::HOME);
    let samples =
        sets::simulate(&head_rig, SetKind::Train, &postures, &SimOptions::default()).unwrap();
    let cfg = TrainConfig { hidden: 8, restarts: 2, seed: 5, ..TrainConfig::default() };
    let mut m = train(&sets::dataset(&samples), &cfg).unwrap().blob;
    m.generation = 4;
    assert_eq!(m.topology.inputs, InputKind::StereoJoints);
    let bytes = encode(&m);

    let mut run = boot("posture-model", Some(&bytes), None);
    let i = info(&mut run);
    assert_network(&i, Slot::A, 4);
    let mi = i.model.expect("model metadata");
    assert_eq!((mi.inputs, mi.hidden, mi.outputs), (9, 8, 3));

    // The host runs the same head from the same boot.
    let mut host =
        Head::new(head::boot(&bytes, &[]), GazeConfig::DEFAULT, &ControllerConfig::DEFAULT)
            .unwrap();
    let seen = |j: &Joints, p: &[f64; 3]| {
        let px = head_rig.project_rounded(j, p).unwrap();
        StereoPoint { u_l: px[0] as f32, v_l: px[1] as f32, u_r: px[2] as f32, v_r: px[3] as f32 }
    };
    let infer = |j: &Joints, p: &StereoPoint| {
        let mut x = p.to_array().to_vec();
        x.extend_from_slice(&j.0);
        let mut y = [0.0f32; 3];
        m.infer(&x, &mut y).unwrap();
        y
    };
    let bits = |e: &protocol::EstimateData| [e.x, e.y, e.z].map(f32::to_bits);

    // Look at a point left of and above the straight-ahead direction, 90 cm away.
    let target = [-6.0, -3.0, 90.0];
    let p0 = seen(&Joints::HOME, &target);
    let ResponseBody::Look(l) = run.link.request(RequestBody::Look(p0)).unwrap() else {
        panic!("Look refused")
    };
    assert_eq!(l, host.look(&p0).unwrap());
    assert_eq!(bits(&l.estimate), infer(&Joints::HOME, &p0).map(f32::to_bits));
    let moved = l.target;
    assert!(GazeConfig::DEFAULT.limits.contains(&moved));
    // The eyes verge on the target (about 6.7 degrees) and turn left and up.
    let verg = moved[Axis::RightEyePan] - moved[Axis::LeftEyePan];
    assert!((5.5..8.0).contains(&verg), "{moved:?}");
    assert!(moved[Axis::NeckPan] > 0.0 && moved[Axis::LeftEyePan] + moved[Axis::RightEyePan] > 0.0);
    assert!(moved[Axis::NeckTilt] + moved[Axis::EyeTilt] < 0.0, "{moved:?}");
    // Let the move finish (neck 0.7 s).
    std::thread::sleep(Duration::from_millis(1500));
    while host.controller.is_moving() {
        host.tick();
    }
    assert_eq!(host.joints(), moved);

    // Points seen from the new posture: the head feeds its setpoints to the net.
    for p in [[-6.0, -3.0, 90.0], [-4.0, -1.0, 120.0], [-8.5, -4.0, 75.0]] {
        let px = seen(&moved, &p);
        let e = estimate(&mut run, px);
        assert_eq!(bits(&e), infer(&moved, &px).map(f32::to_bits), "{p:?}");
        assert_eq!(Ok(e), host.estimate(&px));
        assert_eq!(e.source, Source::Network);
        // The same pixels read at home would put the point elsewhere.
        let at_home = infer(&Joints::HOME, &px);
        assert!((at_home[2] - e.z).abs() > 5.0, "{p:?}: {at_home:?} vs {e:?}");
        // And the estimate is right: depth within 5 % (floor about 1.3 %), 3-D within 5 cm.
        let err = ((e.x as f64 - p[0]).powi(2)
            + (e.y as f64 - p[1]).powi(2)
            + (e.z as f64 - p[2]).powi(2))
        .sqrt();
        eprintln!(
            "posture {:?}: true {p:?}, head ({}, {}, {}), error {err:.2} cm; read at home z = {}",
            moved.0, e.x, e.y, e.z, at_home[2]
        );
        assert!((e.z as f64 - p[2]).abs() < 0.05 * p[2], "{p:?}: {e:?}");
        assert!(err < 5.0, "{p:?}: {e:?} ({err} cm)");
    }
}
