//! `hvs view`'s HTTP server (`axum` on `tokio`): the embedded page, the frames and the JSON
//! API of [`super::api`] over a [`Session`]. Only fixed routes exist (no request path
//! reaches the file system); bodies are capped at [`MAX_BODY`] bytes; every malformed
//! request gets a 4xx and the server carries on. Off loopback every request must carry the
//! token printed at start (`?token=`, as Jupyter does). SIGINT or SIGTERM stop it at once.

use super::api::{self, LocateRequest, LookRequest, RetrainRequest};
use super::assets;
use super::frames::View;
use super::session::{DepthView, Refused, Session};
use anyhow::{Context, Result};
use axum::body::Body;
use axum::extract::{DefaultBodyLimit, Path, RawQuery, Request, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde_json::json;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The largest request body accepted (bytes): a click or a list of ticks is far smaller.
pub const MAX_BODY: usize = 64 * 1024;

struct App {
    session: Session,
    token: Option<String>,
    training: AtomicBool,
}

type Shared = Arc<App>;

/// An error answer: a status and a one-line message, as JSON `{"error": ...}`.
struct ApiError(StatusCode, String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, Json(json!({"error": self.1}))).into_response()
    }
}

/// A JSON request body whose refusal (malformed JSON, a missing, unknown or mistyped field,
/// another content type) is an [`ApiError`] like every other: `{"error": ...}` on one line,
/// with the status axum gives it (400, 415 or 422).
struct JsonBody<T>(T);

impl<S: Send + Sync, T: serde::de::DeserializeOwned> axum::extract::FromRequest<S> for JsonBody<T> {
    type Rejection = ApiError;

    async fn from_request(req: axum::extract::Request, state: &S) -> Result<Self, ApiError> {
        match Json::<T>::from_request(req, state).await {
            Ok(Json(v)) => Ok(JsonBody(v)),
            Err(r) => Err(ApiError(r.status(), r.body_text().replace('\n', " "))),
        }
    }
}

/// The path's parameters (a pair number, a view), whose refusal (`/api/frame/-1/left`) is an
/// [`ApiError`] like every other, not axum's plain-text one.
struct Segments<T>(T);

impl<S: Send + Sync, T: serde::de::DeserializeOwned + Send> axum::extract::FromRequestParts<S>
    for Segments<T>
{
    type Rejection = ApiError;

    async fn from_request_parts(
        parts: &mut axum::http::request::Parts,
        state: &S,
    ) -> Result<Self, ApiError> {
        match Path::<T>::from_request_parts(parts, state).await {
            Ok(Path(v)) => Ok(Segments(v)),
            Err(r) => Err(ApiError(r.status(), r.body_text().replace('\n', " "))),
        }
    }
}

impl From<Refused> for ApiError {
    fn from(r: Refused) -> ApiError {
        match r {
            Refused::Bad(m) => ApiError(StatusCode::BAD_REQUEST, m),
            Refused::NotFound(m) => ApiError(StatusCode::NOT_FOUND, m),
            Refused::Unprocessable(m) => ApiError(StatusCode::UNPROCESSABLE_ENTITY, m),
            Refused::Unavailable(m) => ApiError(StatusCode::SERVICE_UNAVAILABLE, m),
        }
    }
}

/// A random token of 32 hex digits from the operating system's randomness.
pub fn random_token() -> Result<String> {
    let mut b = [0u8; 16];
    getrandom::fill(&mut b).map_err(|e| anyhow::anyhow!("no OS randomness for the token: {e}"))?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

/// Whether `addr` needs a token: anything but a loopback address.
pub fn needs_token(addr: &SocketAddr) -> bool {
    !addr.ip().is_loopback()
}

/// Serves `session` on `addr` until SIGINT or SIGTERM. `started` gets the page's URL (the
/// real port when `addr` asks for port 0; the token when one is needed) once it listens.
pub fn serve(
    session: Session,
    addr: SocketAddr,
    started: impl FnOnce(&str) -> Result<()>,
) -> Result<()> {
    let token = if needs_token(&addr) { Some(random_token()?) } else { None };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the async runtime")?;
    let app = Arc::new(App { session, token, training: AtomicBool::new(false) });
    let result = rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("--listen {addr}: cannot listen"))?;
        let real = listener.local_addr().context("cannot read the bound address")?;
        let query = app.token.as_ref().map_or_else(String::new, |t| format!("?token={t}"));
        // The handlers are installed before the address is printed: a SIGINT right after
        // it stops the server cleanly, never by the default action.
        use tokio::signal::unix::{signal, SignalKind};
        let mut int = signal(SignalKind::interrupt()).context("cannot watch SIGINT")?;
        let mut term = signal(SignalKind::terminate()).context("cannot watch SIGTERM")?;
        started(&format!("http://{real}/{query}"))?;
        let router = router(app);
        tokio::select! {
            r = axum::serve(listener, router) => r.context("the server stopped"),
            _ = int.recv() => Ok(()),
            _ = term.recv() => Ok(()),
        }
    });
    // Requests still running (a retrain) are not waited for.
    rt.shutdown_background();
    result
}

fn router(app: Shared) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/app.js", get(|| async { asset("text/javascript", assets::APP_JS) }))
        .route("/style.css", get(|| async { asset("text/css", assets::STYLE_CSS) }))
        .route("/api/session", get(session))
        .route("/api/frame/{pair}/{view}", get(frame))
        .route("/api/locate", post(locate))
        .route("/api/head", get(head))
        .route("/api/look", post(look))
        .route("/api/depth/{pair}", get(depth))
        .route("/api/depth/{pair}/image", get(depth_image))
        .route("/api/depth/{pair}/cloud.ply", get(depth_cloud))
        .route("/api/captures", get(captures))
        .route("/api/retrain", post(retrain))
        .fallback(|| async { ApiError(StatusCode::NOT_FOUND, "no such page".into()) })
        .method_not_allowed_fallback(|| async {
            ApiError(StatusCode::METHOD_NOT_ALLOWED, "this method is not served here".into())
        })
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .layer(middleware::from_fn_with_state(app.clone(), check_token))
        .with_state(app)
}

fn asset(kind: &'static str, text: impl Into<Body>) -> Response {
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static(kind)),
            (header::CACHE_CONTROL, HeaderValue::from_static("no-cache")),
        ],
        text.into(),
    )
        .into_response()
}

/// The page; off loopback its stylesheet and script are asked for with the token (the page
/// itself was, or it would not be served), since a browser asks for them without the page's
/// query.
async fn index(State(app): State<Shared>) -> Response {
    match &app.token {
        None => asset("text/html; charset=utf-8", assets::INDEX_HTML),
        Some(t) => {
            let page = assets::INDEX_HTML
                .replace("href=\"style.css\"", &format!("href=\"style.css?token={t}\""))
                .replace("src=\"app.js\"", &format!("src=\"app.js?token={t}\""));
            asset("text/html; charset=utf-8", page)
        }
    }
}

/// Off loopback, every request needs `token=<the token>` in its query.
async fn check_token(State(app): State<Shared>, req: Request, next: Next) -> Response {
    if let Some(want) = &app.token {
        let given = param(req.uri().query(), "token");
        if !given.is_some_and(|g| same(g.as_bytes(), want.as_bytes())) {
            return ApiError(
                StatusCode::FORBIDDEN,
                "this server needs its token: open the URL hvs view printed".into(),
            )
            .into_response();
        }
    }
    next.run(req).await
}

/// The value of the first `key=value` (or bare `key`: empty) of a request's query, if any.
fn param<'a>(query: Option<&'a str>, key: &str) -> Option<&'a str> {
    query?.split('&').find_map(|kv| {
        let rest = kv.strip_prefix(key)?;
        if rest.is_empty() {
            Some(rest)
        } else {
            rest.strip_prefix('=')
        }
    })
}

/// Compares in time independent of where the strings differ.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn session(State(app): State<Shared>) -> Response {
    Json(api::session(&app.session)).into_response()
}

/// The longest a `?after=` request waits for a newer frame before it answers with the latest.
pub const FRAME_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// A frame request's query: `after=S` waits (up to [`FRAME_WAIT`]) for a frame newer than
/// number `S`, `seq=S` asks for frame `S` (while the store keeps it: the right image of the
/// pair whose left one the page has). Other parameters (`token`, a cache-buster) are ignored.
fn frame_query(query: Option<&str>) -> Result<(Option<u64>, Option<u64>), ApiError> {
    let number = |k: &str| {
        param(query, k)
            .map(|v| {
                v.parse::<u64>().map_err(|_| {
                    ApiError(StatusCode::BAD_REQUEST, format!("{k}={v:?}: not a frame number"))
                })
            })
            .transpose()
    };
    Ok((number("after")?, number("seq")?))
}

async fn frame(
    State(app): State<Shared>,
    Segments((pair, view)): Segments<(usize, String)>,
    RawQuery(query): RawQuery,
) -> Result<Response, ApiError> {
    let view = View::parse(&view).ok_or_else(|| {
        ApiError(
            StatusCode::NOT_FOUND,
            format!("{view:?}: not a view (left, right, left-corners, right-corners)"),
        )
    })?;
    let (after, seq) = frame_query(query.as_deref())?;
    app.session.check_pair(pair)?;
    let frames = app.session.frames.clone();
    if let Some(after) = after.filter(|_| frames.live()) {
        let t0 = Instant::now();
        while frames.latest_seq() <= after && t0.elapsed() < FRAME_WAIT {
            tokio::time::sleep(std::time::Duration::from_millis(3)).await;
        }
    }
    let f = tokio::task::spawn_blocking(move || match seq {
        Some(seq) => frames.frame_at(pair, view, seq).ok_or_else(|| not_kept(&*frames, seq)),
        None => frames.frame(pair, view).ok_or(None),
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
    .map_err(|why| {
        let why = why.unwrap_or_else(|| "no such frame".into());
        ApiError(StatusCode::NOT_FOUND, format!("pair {pair}: {why}"))
    })?;
    let mut r = png_response(&f.png);
    r.headers_mut().insert("x-frame-seq", HeaderValue::from(f.seq));
    Ok(r)
}

/// Why frame `seq` is not served: the frames the store keeps, when `seq` is not one of them
/// (`None`: it is, but has no such view).
fn not_kept(frames: &dyn super::frames::PairStore, seq: u64) -> Option<String> {
    match frames.kept_seqs() {
        Some((a, b)) if (a..=b).contains(&seq) => None,
        Some((a, b)) if a == b => {
            Some(format!("frame {seq} is not kept: the server keeps frame {a} only"))
        }
        Some((a, b)) => {
            Some(format!("frame {seq} is not kept: the server keeps frames {a} to {b}"))
        }
        None => Some(format!("frame {seq} is not kept: the server keeps no frame yet")),
    }
}

/// A PNG answer, never cached (frames change; a depth map is the page's to keep).
fn png_response(png: &[u8]) -> Response {
    let mut r = Response::new(Body::from(png.to_vec()));
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static("image/png"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    r
}

async fn locate(
    State(app): State<Shared>,
    JsonBody(q): JsonBody<LocateRequest>,
) -> Result<Response, ApiError> {
    let t0 = Instant::now();
    let a = app.clone();
    let found = tokio::task::spawn_blocking(move || a.session.locate(q.pair, q.u, q.v))
        .await
        .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))??;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok(Json(api::located(q.pair, &found, ms)).into_response())
}

async fn head(State(app): State<Shared>) -> Result<Response, ApiError> {
    let head = app.session.head.as_ref().ok_or_else(|| {
        ApiError(StatusCode::NOT_FOUND, "not a live head: start hvs view with --scene".into())
    })?;
    let s = head.state().ok_or_else(|| ApiError(StatusCode::NOT_FOUND, "no frame yet".into()))?;
    Ok(Json(api::head(&s)).into_response())
}

async fn look(
    State(app): State<Shared>,
    JsonBody(q): JsonBody<LookRequest>,
) -> Result<Response, ApiError> {
    let s = app.session.look(q.goal())?;
    Ok(Json(api::head(&s)).into_response())
}

/// The depth map of a pair, computed on a blocking thread the first time.
async fn depth_of(app: &Shared, pair: usize) -> Result<Arc<DepthView>, ApiError> {
    let a = app.clone();
    Ok(tokio::task::spawn_blocking(move || a.session.depth(pair))
        .await
        .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))??)
}

async fn depth(
    State(app): State<Shared>,
    Segments(pair): Segments<usize>,
) -> Result<Response, ApiError> {
    let d = depth_of(&app, pair).await?;
    Ok(Json(api::depth(pair, &d)).into_response())
}

async fn depth_image(
    State(app): State<Shared>,
    Segments(pair): Segments<usize>,
) -> Result<Response, ApiError> {
    Ok(png_response(&depth_of(&app, pair).await?.png))
}

/// `GET /api/depth/{pair}/cloud.ply`: the pair's point cloud, the bytes of `hvs depth
/// --thorough --ply`.
async fn depth_cloud(
    State(app): State<Shared>,
    Segments(pair): Segments<usize>,
) -> Result<Response, ApiError> {
    let d = depth_of(&app, pair).await?;
    let cloud = tokio::task::spawn_blocking(move || d.cloud())
        .await
        .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))?
        .map_err(ApiError::from)?;
    let mut r = Response::new(Body::from(cloud.to_vec()));
    let h = r.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static("application/octet-stream"));
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    Ok(r)
}

async fn captures(State(app): State<Shared>) -> Result<Response, ApiError> {
    api::captures(&app.session)
        .map(|v| Json(v).into_response())
        .ok_or_else(|| ApiError(StatusCode::NOT_FOUND, "not a capture set".into()))
}

async fn retrain(State(app): State<Shared>, req: Request) -> Result<Response, ApiError> {
    use axum::extract::FromRequest;
    // A session without a capture set refuses whatever the body holds.
    app.session.capture_set()?;
    let JsonBody(q) = JsonBody::<RetrainRequest>::from_request(req, &()).await?;
    if app.training.swap(true, Ordering::SeqCst) {
        return Err(ApiError(StatusCode::CONFLICT, "a retrain is already running".into()));
    }
    let t0 = Instant::now();
    let a = app.clone();
    let r = tokio::task::spawn_blocking(move || {
        let r = a.session.retrain(&q.ticked);
        a.training.store(false, Ordering::SeqCst);
        r
    })
    .await
    .map_err(|e| ApiError(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()))??;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok(Json(api::retrained(&r, ms)).into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn query_parameters_are_found_by_their_whole_key() {
        let q = Some("token=ab&after=3&afterx=9&seq");
        assert_eq!(param(q, "after"), Some("3"));
        assert_eq!(param(q, "token"), Some("ab"));
        assert_eq!(param(q, "seq"), Some(""));
        assert_eq!(param(q, "n"), None);
        assert_eq!(param(None, "after"), None);
        assert!(frame_query(Some("after=x")).is_err() && frame_query(Some("seq")).is_err());
        assert!(matches!(frame_query(Some("n=4&after=7&seq=2")), Ok((Some(7), Some(2)))));
    }

    #[test]
    fn tokens_are_needed_off_loopback_only_and_compared_whole() {
        for (a, need) in [
            ("127.0.0.1:8080", false),
            ("[::1]:0", false),
            ("0.0.0.0:0", true),
            ("192.168.1.5:8080", true),
            ("[::]:8080", true),
        ] {
            assert_eq!(needs_token(&a.parse().unwrap()), need, "{a}");
        }
        let t = random_token().unwrap();
        assert_eq!(t.len(), 32);
        assert_ne!(t, random_token().unwrap());
        assert!(same(t.as_bytes(), t.clone().as_bytes()));
        assert!(!same(t.as_bytes(), &t.as_bytes()[..31]));
        assert!(!same(b"abcd", b"abce"));
        assert!(!same(b"", b"a"));
    }
}
