//! Client side of the head protocol (`hvs_shared::runtime::protocol`) over TCP (QEMU) or a serial port.
//!
//! [`Link`] numbers requests, sends them as COBS frames, and waits for the response with the
//! same id under a timeout; frames the head sends on its own (`Ready`, errors about frames it
//! could not read) are kept apart in [`Link::unsolicited`]. [`Link::wait_ready`] pings until the
//! head answers, since bytes sent before the firmware enables its USART are lost.

use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::protocol::{
    self, FrameAccumulator, Request, RequestBody, Response, ResponseBody, MAX_FRAME_LEN,
    UNSOLICITED_ID,
};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::str::FromStr;
use std::time::{Duration, Instant};

/// Where the head is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// `tcp:HOST:PORT` (QEMU's serial server, or a serial-to-TCP bridge).
    Tcp(String),
    /// A serial port (`/dev/ttyUSB0`, `COM3`) at `baud`.
    Serial {
        /// Port name.
        path: String,
        /// Baud rate.
        baud: u32,
    },
}

impl FromStr for Endpoint {
    type Err = anyhow::Error;

    /// Parses `tcp:HOST:PORT` or `serial:PATH[@BAUD]`.
    fn from_str(s: &str) -> Result<Self> {
        if let Some(addr) = s.strip_prefix("tcp:") {
            let Some((host, port)) = addr.rsplit_once(':').filter(|(h, _)| !h.is_empty()) else {
                bail!("endpoint {s:?}: expected tcp:HOST:PORT");
            };
            if port.parse::<u16>().is_err() {
                bail!(
                    "endpoint {s:?}: the port {port:?} of {host} is not a number from 0 to 65535"
                );
            }
            return Ok(Endpoint::Tcp(addr.to_string()));
        }
        if let Some(rest) = s.strip_prefix("serial:") {
            let (path, baud) = match rest.rsplit_once('@') {
                Some((p, b)) => (
                    p,
                    b.parse().with_context(|| format!("endpoint {s:?}: bad baud rate {b:?}"))?,
                ),
                None => (rest, protocol::BAUD_RATE),
            };
            if path.is_empty() {
                bail!("endpoint {s:?}: empty serial port name");
            }
            return Ok(Endpoint::Serial { path: path.to_string(), baud });
        }
        bail!("endpoint {s:?}: expected tcp:HOST:PORT or serial:PATH[@BAUD]")
    }
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Endpoint::Tcp(a) => write!(f, "tcp:{a}"),
            Endpoint::Serial { path, baud } => write!(f, "serial:{path}@{baud}"),
        }
    }
}

trait Port: Read + Write + Send {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()>;
}

impl Port for TcpStream {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        self.set_read_timeout(Some(t.max(Duration::from_millis(1))))
    }
}

impl Port for Box<dyn serialport::SerialPort> {
    fn set_timeout(&mut self, t: Duration) -> std::io::Result<()> {
        serialport::SerialPort::set_timeout(self.as_mut(), t.max(Duration::from_millis(1)))
            .map_err(std::io::Error::other)
    }
}

/// An open connection to a head.
pub struct Link {
    port: Box<dyn Port>,
    endpoint: Endpoint,
    acc: FrameAccumulator<MAX_FRAME_LEN>,
    frames: VecDeque<Result<Response, protocol::ProtocolError>>,
    next_id: u32,
    /// How long [`Link::request`] waits for its response.
    pub timeout: Duration,
    /// Frames with the unsolicited id received while waiting for responses (oldest first).
    pub unsolicited: Vec<Response>,
}

impl Link {
    /// Opens `endpoint`. A TCP connection is retried until `connect_timeout` has passed (QEMU
    /// may still be starting); a serial port is opened once.
    pub fn open(endpoint: &Endpoint, connect_timeout: Duration) -> Result<Link> {
        let port: Box<dyn Port> = match endpoint {
            Endpoint::Tcp(addr) => {
                let start = Instant::now();
                let stream = loop {
                    match TcpStream::connect(addr) {
                        Ok(s) => break s,
                        Err(e) if start.elapsed() < connect_timeout => {
                            let _ = e;
                            std::thread::sleep(Duration::from_millis(50));
                        }
                        Err(e) => {
                            return Err(e).with_context(|| {
                                format!("{endpoint}: cannot connect within {connect_timeout:?} (is `hvs emulate` running there? a head on a serial port is --port DEVICE)")
                            })
                        }
                    }
                };
                stream.set_nodelay(true).ok();
                Box::new(stream)
            }
            Endpoint::Serial { path, baud } => {
                let p = serialport::new(path, *baud)
                    .timeout(Duration::from_millis(100))
                    .open()
                    .with_context(|| format!("{endpoint}: cannot open serial port"))?;
                Box::new(p)
            }
        };
        Ok(Link {
            port,
            endpoint: endpoint.clone(),
            acc: FrameAccumulator::new(),
            frames: VecDeque::new(),
            next_id: 1,
            timeout: Duration::from_secs(2),
            unsolicited: Vec::new(),
        })
    }

    /// The endpoint this link talks to.
    pub fn endpoint(&self) -> &Endpoint {
        &self.endpoint
    }

    /// Pings until the head answers (every 200 ms, until `deadline` has passed).
    pub fn wait_ready(&mut self, deadline: Duration) -> Result<()> {
        let start = Instant::now();
        loop {
            let id = self.send(RequestBody::Ping)?;
            let until = Instant::now() + Duration::from_millis(200);
            while let Some(r) = self.recv_until(until)? {
                if r.id == id && r.body == ResponseBody::Pong {
                    return Ok(());
                }
                // Earlier pings' Pongs and the boot announcement are expected here.
            }
            if start.elapsed() >= deadline {
                bail!(
                    "{}: no answer to Ping within {deadline:?}: the head is not running (under `hvs emulate`: is the firmware the `--features qemu` build?), or is busy with another client (QEMU serves one connection at a time; close the other `hvs head`)",
                    self.endpoint
                );
            }
        }
    }

    /// Sends `body` with a fresh id; returns the id.
    pub fn send(&mut self, body: RequestBody) -> Result<u32> {
        let id = self.next_id;
        self.next_id = self.next_id.checked_add(1).unwrap_or(1).max(1);
        let mut buf = [0u8; MAX_FRAME_LEN];
        let frame = protocol::encode_request(&Request { id, body }, &mut buf)
            .map_err(|e| anyhow!("encoding request: {e}"))?;
        self.send_raw(frame)?;
        Ok(id)
    }

    /// Writes raw bytes (tests use it to inject garbage).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<()> {
        self.port
            .write_all(bytes)
            .and_then(|_| self.port.flush())
            .with_context(|| format!("{}: write failed", self.endpoint))
    }

    /// Sends `body` and returns the answer with the same id, within [`Link::timeout`].
    pub fn request(&mut self, body: RequestBody) -> Result<ResponseBody> {
        let id = self.send(body)?;
        let until = Instant::now() + self.timeout;
        while let Some(r) = self.recv_until(until)? {
            if r.id == id {
                return Ok(r.body);
            }
        }
        bail!("{}: no response to request {id} ({body:?}) within {:?}", self.endpoint, self.timeout)
    }

    /// The next well-formed frame received before `until`, or `None` on timeout. Frames that
    /// are not valid responses are skipped; frames with the unsolicited id are returned and
    /// also recorded in [`Link::unsolicited`].
    pub fn recv_until(&mut self, until: Instant) -> Result<Option<Response>> {
        loop {
            while let Some(f) = self.frames.pop_front() {
                if let Ok(r) = f {
                    if r.id == UNSOLICITED_ID {
                        self.unsolicited.push(r);
                    }
                    return Ok(Some(r));
                }
            }
            let now = Instant::now();
            if now >= until {
                return Ok(None);
            }
            self.port
                .set_timeout(until - now)
                .with_context(|| format!("{}: cannot set timeout", self.endpoint))?;
            let mut buf = [0u8; 256];
            match self.port.read(&mut buf) {
                Ok(0) => bail!("{}: connection closed by the head", self.endpoint),
                Ok(n) => {
                    for &b in &buf[..n] {
                        if let Some(r) = self.acc.push(b) {
                            self.frames.push_back(r.and_then(protocol::decode_response));
                        }
                    }
                }
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e).with_context(|| format!("{}: read failed", self.endpoint)),
            }
        }
    }
}

/// A test head's side of a TCP link: each request frame `stream` brings, to `answer` (with a
/// second handle of the stream to write the answer to), until the stream ends or `answer`
/// fails.
#[cfg(test)]
pub(crate) fn serve_frames(
    stream: std::net::TcpStream,
    mut answer: impl FnMut(&mut [u8], &mut std::net::TcpStream) -> std::io::Result<()>,
) {
    let (mut r, mut w) = (stream.try_clone().expect("a second handle"), stream);
    let (mut acc, mut buf) = (FrameAccumulator::<MAX_FRAME_LEN>::new(), [0u8; 64]);
    loop {
        let n = match r.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        for &b in &buf[..n] {
            let Some(Ok(f)) = acc.push(b) else { continue };
            if answer(f, &mut w).is_err() {
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::runtime::protocol::StereoPoint;
    use std::net::TcpListener;

    #[test]
    fn endpoints_parse_and_reject_nonsense() {
        assert_eq!(
            "tcp:127.0.0.1:4444".parse::<Endpoint>().unwrap(),
            Endpoint::Tcp("127.0.0.1:4444".into())
        );
        assert_eq!(
            "serial:/dev/ttyUSB0@9600".parse::<Endpoint>().unwrap(),
            Endpoint::Serial { path: "/dev/ttyUSB0".into(), baud: 9600 }
        );
        assert_eq!(
            "serial:COM3".parse::<Endpoint>().unwrap(),
            Endpoint::Serial { path: "COM3".into(), baud: 115_200 }
        );
        for bad in ["tcp:4444", "tcp::1", "tcp:host:99999", "udp:x:1", "serial:", "serial:x@fast"] {
            assert!(bad.parse::<Endpoint>().is_err(), "{bad}");
        }
    }

    /// A fake head on a TCP socket: answers Ping with Pong, Estimate with a fixed point, sends
    /// an unsolicited Ready first and a junk frame before each answer.
    fn fake_head() -> (String, std::thread::JoinHandle<()>) {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap().to_string();
        let h = std::thread::spawn(move || {
            let (mut s, _) = l.accept().unwrap();
            let mut out = [0u8; MAX_FRAME_LEN];
            let ready = Response {
                id: 0,
                body: ResponseBody::Ready { protocol: protocol::PROTOCOL_VERSION },
            };
            s.write_all(protocol::encode_response(&ready, &mut out).unwrap()).unwrap();
            serve_frames(s, |f, s| {
                let req = protocol::decode_request(f).unwrap();
                let body = match req.body {
                    RequestBody::Ping => ResponseBody::Pong,
                    RequestBody::Estimate(p) => ResponseBody::Estimate(protocol::EstimateData {
                        x: p.u_l,
                        y: p.v_l,
                        z: 100.0,
                        source: protocol::Source::Network,
                        in_range: true,
                    }),
                    _ => ResponseBody::Error(protocol::ErrorCode::Unsupported),
                };
                s.write_all(&[0x07, 0x07, 0x00])?;
                s.write_all(
                    protocol::encode_response(&Response { id: req.id, body }, &mut out).unwrap(),
                )
            });
        });
        (addr, h)
    }

    #[test]
    fn request_matches_ids_and_skips_junk() {
        let (addr, h) = fake_head();
        let mut link = Link::open(&Endpoint::Tcp(addr), Duration::from_secs(5)).unwrap();
        link.wait_ready(Duration::from_secs(5)).unwrap();
        let p = StereoPoint { u_l: 1.5, v_l: -2.0, u_r: 0.0, v_r: 0.0 };
        match link.request(RequestBody::Estimate(p)).unwrap() {
            ResponseBody::Estimate(e) => assert_eq!((e.x, e.y, e.z), (1.5, -2.0, 100.0)),
            other => panic!("{other:?}"),
        }
        assert_eq!(
            link.request(RequestBody::Home).unwrap(),
            ResponseBody::Error(protocol::ErrorCode::Unsupported)
        );
        assert!(link.unsolicited.iter().any(|r| matches!(r.body, ResponseBody::Ready { .. })));
        drop(link);
        h.join().unwrap();
    }

    #[test]
    fn silent_head_times_out_with_a_clear_error() {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = l.local_addr().unwrap().to_string();
        let mut link = Link::open(&Endpoint::Tcp(addr.clone()), Duration::from_secs(5)).unwrap();
        link.timeout = Duration::from_millis(100);
        let err = link.request(RequestBody::Info).unwrap_err().to_string();
        assert!(err.contains(&addr) && err.contains("no response"), "{err}");
        let err = link.wait_ready(Duration::from_millis(300)).unwrap_err().to_string();
        assert!(err.contains("no answer to Ping"), "{err}");
    }
}
