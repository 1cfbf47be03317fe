//! The HTTP server: the page (bundled into the binary), the JSON API and the
//! server-sent event stream.
//!
//! | route | what |
//! |---|---|
//! | `GET /` , `/app.js`, `/app.css` | the page (built from `ground/web`, no CDN) |
//! | `GET /api/mib` | TC forms, parameters, events, states, mode tree |
//! | `GET /api/snapshot` | the whole picture and the ID of its last message |
//! | `GET /api/stream?since=ID` | SSE; resumes from `Last-Event-ID` |
//! | `POST /api/tc` | `{"robot", "name", "args", "confirm"}` → `{"request_id"}` |
//! | `GET /api/tc/{request_id}` | the TC and its PUS 1 stages |
//! | `POST /api/alarms/{id}/ack`, `/shelve` | `{"minutes"}` for shelve |
//! | `GET /api/plans`, `POST /api/plans` | `{"name", "confirm"}` → `{"run_id"}` (404 unknown, 409 busy or not confirmed) |
//! | `POST /api/robots/{robot}/onboard/{suspend,resume,abort,skip}` | `{"confirm", "step"}` → `{"request_id"}`: the on-board plan's control TC (404 unknown robot or control, 503 link not up, 409 plan state or not confirmed) |
//! | `GET /api/series?robot&param&t0&t1&columns` | min/max per column, archive + live |
//!
//! Access: without a token the server binds to loopback addresses only and checks
//! the `Host` header (no DNS rebinding from a web page); with a token every `/api`
//! request needs it (`Authorization: Bearer T` or `?token=T`).

use std::collections::{BTreeMap, VecDeque};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures_util::stream::{self, Stream};
use serde::Deserialize;
use serde_json::{json, Map, Value};
use tokio::sync::broadcast::error::RecvError;
use tower_http::set_header::SetResponseHeaderLayer;

use super::hub::Resume;
use super::{mibinfo, CommandRecord, Commander, Hub, LinkState, PlanControl, PlanStartError, Series};

const INDEX_HTML: &str = include_str!("../../web/dist/index.html");
const APP_JS: &str = include_str!("../../web/dist/app.js");
const APP_CSS: &str = include_str!("../../web/dist/app.css");

/// Largest number of plot columns a request may ask for.
const MAX_COLUMNS: usize = 4000;

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServeError {
    #[error("binding the dashboard to {0} (not a loopback address) needs an access token (--http-token)")]
    TokenRequired(SocketAddr),
    #[error("dashboard: cannot listen on {addr}: {err}")]
    Bind { addr: SocketAddr, err: std::io::Error },
    #[error("dashboard: {0}")]
    Io(#[from] std::io::Error),
}

#[derive(Clone)]
struct App {
    hub: Hub,
    commander: Arc<dyn Commander>,
    series: Arc<dyn Series>,
    token: Option<Arc<str>>,
}

fn router(app: App) -> Router {
    let api = Router::new()
        .route("/api/mib", get(|| async { Json(mibinfo::page_mib()) }))
        .route("/api/snapshot", get(snapshot))
        .route("/api/stream", get(sse))
        .route("/api/tc", post(send_tc).get(list_tc))
        .route("/api/tc/{request_id}", get(get_tc))
        .route("/api/alarms/{id}/ack", post(ack_alarm))
        .route("/api/alarms/{id}/shelve", post(shelve_alarm))
        .route("/api/plans", get(plans).post(start_plan))
        .route("/api/robots/{robot}/onboard/{control}", post(onboard_control))
        .route("/api/series", get(series))
        .route_layer(middleware::from_fn_with_state(app.clone(), guard))
        .layer(SetResponseHeaderLayer::overriding(
            header::CACHE_CONTROL,
            HeaderValue::from_static("no-store"),
        ));
    Router::new()
        .route("/", get(|| async { page(INDEX_HTML, "text/html; charset=utf-8") }))
        .route(
            "/app.js",
            get(|| async { page(APP_JS, "text/javascript; charset=utf-8") }),
        )
        .route("/app.css", get(|| async { page(APP_CSS, "text/css; charset=utf-8") }))
        .merge(api)
        .layer(SetResponseHeaderLayer::overriding(
            header::CONTENT_SECURITY_POLICY,
            HeaderValue::from_static(
                "default-src 'self'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; connect-src 'self'",
            ),
        ))
        .with_state(app)
}

fn page(body: &'static str, ctype: &'static str) -> Response {
    ([(header::CONTENT_TYPE, ctype)], body).into_response()
}

fn error(status: StatusCode, msg: impl Into<String>) -> Response {
    (status, Json(json!({"error": msg.into()}))).into_response()
}

fn check_binding(addr: SocketAddr, token: &Option<String>) -> Result<(), ServeError> {
    if token.is_none() && !addr.ip().is_loopback() {
        return Err(ServeError::TokenRequired(addr));
    }
    Ok(())
}

fn app(token: Option<String>, hub: Hub, commander: Arc<dyn Commander>, series: Arc<dyn Series>) -> App {
    App {
        hub,
        commander,
        series,
        token: token.filter(|t| !t.is_empty()).map(Arc::from),
    }
}

/// Serves the dashboard on `addr` until the task is dropped. Refuses a non-loopback
/// address without a token.
pub async fn serve(
    addr: SocketAddr,
    token: Option<String>,
    hub: Hub,
    commander: Arc<dyn Commander>,
    series: Arc<dyn Series>,
) -> Result<(), ServeError> {
    check_binding(addr, &token)?;
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|err| ServeError::Bind { addr, err })?;
    axum::serve(listener, router(app(token, hub, commander, series))).await?;
    Ok(())
}

/// A dashboard server running on its own threads (see [`spawn`]).
pub struct Running {
    addr: SocketAddr,
    stop: Option<tokio::sync::watch::Sender<bool>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Running {
    /// The address it listens on (the real port when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }
    /// Stops the server and waits for its threads.
    pub fn stop(mut self) {
        self.shutdown();
    }
    fn shutdown(&mut self) {
        if let Some(s) = self.stop.take() {
            // The server may have ended already; nothing to stop then.
            let _already_stopped = s.send(true);
        }
        if let Some(t) = self.thread.take() {
            // A panicked server thread has nothing left to clean up.
            let _panicked = t.join();
        }
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Starts the dashboard on its own tokio runtime (two worker threads), for callers
/// that are not async. Binds before returning, so errors are reported here.
pub fn spawn(
    addr: SocketAddr,
    token: Option<String>,
    hub: Hub,
    commander: Arc<dyn Commander>,
    series: Arc<dyn Series>,
) -> Result<Running, ServeError> {
    check_binding(addr, &token)?;
    let std_listener = std::net::TcpListener::bind(addr).map_err(|err| ServeError::Bind { addr, err })?;
    std_listener.set_nonblocking(true)?;
    let local = std_listener.local_addr()?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("dashboard")
        .enable_all()
        .build()?;
    let (tx, rx) = tokio::sync::watch::channel(false);
    let router = router(app(token, hub, commander, series));
    let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), std::io::Error>>();
    let thread = std::thread::Builder::new().name("dashboard".into()).spawn(move || {
        rt.block_on(async move {
            let listener = match tokio::net::TcpListener::from_std(std_listener) {
                Ok(l) => l,
                Err(e) => {
                    let _caller_gone = ready_tx.send(Err(e));
                    return;
                }
            };
            let _caller_gone = ready_tx.send(Ok(()));
            let stop = |mut rx: tokio::sync::watch::Receiver<bool>| async move {
                // A dropped sender also means stop.
                let _stop_or_dropped = rx.wait_for(|s| *s).await;
            };
            let served = axum::serve(listener, router).with_graceful_shutdown(stop(rx.clone()));
            // Open event streams never end by themselves and would hold a graceful
            // shutdown forever: requests get 1 s to finish after the stop.
            tokio::select! {
                r = served => {
                    if let Err(e) = r {
                        eprintln!("dashboard: server ended: {e}");
                    }
                }
                () = async { stop(rx).await; tokio::time::sleep(Duration::from_secs(1)).await } => {}
            }
        });
        rt.shutdown_timeout(Duration::from_secs(1));
    })?;
    match ready_rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => return Err(ServeError::Io(e)),
        Err(_) => return Err(ServeError::Io(std::io::Error::other("dashboard thread ended at start"))),
    }
    Ok(Running {
        addr: local,
        stop: Some(tx),
        thread: Some(thread),
    })
}

/// Token check (when configured) or Host check (loopback without a token).
async fn guard(State(app): State<App>, req: Request, next: Next) -> Response {
    match &app.token {
        Some(token) => {
            let bearer = req
                .headers()
                .get(header::AUTHORIZATION)
                .and_then(|v| v.to_str().ok())
                .and_then(|v| v.strip_prefix("Bearer "));
            let query = req
                .uri()
                .query()
                .and_then(|q| q.split('&').find_map(|kv| kv.strip_prefix("token=")));
            let given = bearer.or(query).unwrap_or("");
            if !constant_time_eq(given.as_bytes(), token.as_bytes()) {
                return error(
                    StatusCode::UNAUTHORIZED,
                    "this dashboard needs its access token: open it as http://HOST:PORT/?token=…",
                );
            }
        }
        None => {
            let host = req
                .headers()
                .get(header::HOST)
                .and_then(|v| v.to_str().ok())
                .unwrap_or("");
            if !loopback_host(host) {
                return error(
                    StatusCode::FORBIDDEN,
                    format!("Host \"{host}\" is not a loopback name; the dashboard has no token so it answers local pages only"),
                );
            }
        }
    }
    next.run(req).await
}

fn loopback_host(host: &str) -> bool {
    let name = if let Some(rest) = host.strip_prefix('[') {
        rest.split(']').next().unwrap_or("")
    } else {
        host.split(':').next().unwrap_or("")
    };
    name.eq_ignore_ascii_case("localhost") || name.parse::<std::net::IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn snapshot(State(app): State<App>) -> Response {
    let mut s = app.hub.snapshot();
    s["server_ms"] = json!(now_ms());
    Json(s).into_response()
}

fn now_ms() -> i64 {
    chrono::Utc::now().timestamp_millis()
}

#[derive(Deserialize)]
struct StreamQuery {
    since: Option<u64>,
}

struct StreamState {
    pending: VecDeque<(u64, Arc<str>)>,
    rx: tokio::sync::broadcast::Receiver<(u64, Arc<str>)>,
    last: u64,
    reset: Option<u64>,
    done: bool,
    hub: Hub,
}

async fn sse(State(app): State<App>, headers: HeaderMap, Query(q): Query<StreamQuery>) -> Response {
    let last_event = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok());
    let since = last_event.or(q.since);
    let st = match app.hub.subscribe(since) {
        Resume::Replay(missed, rx) => StreamState {
            last: missed
                .last()
                .map_or(since.unwrap_or(0), |m| m.0)
                .max(since.unwrap_or(0)),
            pending: missed.into(),
            rx,
            reset: None,
            done: false,
            hub: app.hub.clone(),
        },
        Resume::Reset(newest, rx) => StreamState {
            pending: VecDeque::new(),
            rx,
            last: newest,
            reset: Some(newest),
            done: false,
            hub: app.hub.clone(),
        },
    };
    let sse = Sse::new(events(st)).keep_alive(KeepAlive::new().interval(Duration::from_secs(10)));
    ([("x-accel-buffering", "no")], sse).into_response()
}

fn events(st: StreamState) -> impl Stream<Item = Result<Event, std::convert::Infallible>> {
    stream::unfold(st, |mut st| async move {
        if st.done {
            return None;
        }
        if let Some(newest) = st.reset.take() {
            // The page reloads the snapshot and reconnects from its last ID.
            st.done = true;
            let ev = Event::default()
                .event("reset")
                .data(json!({"last_id": newest}).to_string());
            return Some((Ok(ev), st));
        }
        loop {
            if let Some((id, text)) = st.pending.pop_front() {
                st.last = id;
                return Some((Ok(Event::default().id(id.to_string()).data(&*text)), st));
            }
            match st.rx.recv().await {
                Ok((id, _)) if id <= st.last => continue,
                Ok(m) => st.pending.push_back(m),
                Err(RecvError::Lagged(_)) => {
                    // Fell behind the live stream: same as too far behind the ring.
                    st.hub.count_reset();
                    st.done = true;
                    let newest = st.hub.last_id();
                    let ev = Event::default()
                        .event("reset")
                        .data(json!({"last_id": newest}).to_string());
                    return Some((Ok(ev), st));
                }
                Err(RecvError::Closed) => return None,
            }
        }
    })
}

#[derive(Deserialize)]
struct TcRequest {
    robot: u8,
    name: String,
    #[serde(default)]
    args: Map<String, Value>,
    /// Must be true for TCs the MIB marks hazardous (the page asks the operator).
    #[serde(default)]
    confirm: bool,
    #[serde(default)]
    origin: Option<String>,
}

async fn send_tc(
    State(app): State<App>,
    body: Result<Json<TcRequest>, axum::extract::rejection::JsonRejection>,
) -> Response {
    let Json(req) = match body {
        Ok(b) => b,
        Err(e) => return error(StatusCode::BAD_REQUEST, format!("POST /api/tc: {e}")),
    };
    let Some(def) = mib::tc::by_name(&req.name) else {
        return error(
            StatusCode::BAD_REQUEST,
            format!("no TC named \"{}\" in the MIB", req.name),
        );
    };
    if mib::apid::robot_apid(req.robot).is_none() {
        return error(StatusCode::BAD_REQUEST, format!("robot {} has no APID", req.robot));
    }
    let args = match mibinfo::parse_args(def, &req.args) {
        Ok(a) => a,
        Err(e) => return error(StatusCode::BAD_REQUEST, e),
    };
    if let Some(why) = mibinfo::hazard(def) {
        if !req.confirm {
            return error(
                StatusCode::CONFLICT,
                format!("{} is hazardous ({why}): resend with \"confirm\": true", def.name),
            );
        }
    }
    dispatch(&app, req.robot, def, args, req.origin.unwrap_or_else(|| "page".into())).await
}

/// Hands a checked TC to the commander and records it in the command history under
/// `origin`; answers with its request ID.
async fn dispatch(app: &App, robot: u8, def: &'static mib::tc::TcDef, args: Vec<i64>, origin: String) -> Response {
    let commander = app.commander.clone();
    let name = def.name;
    let raw = args.clone();
    let sent = tokio::task::spawn_blocking(move || commander.send_tc(robot, name, &raw)).await;
    let request_id = match sent {
        Ok(Ok(id)) => id,
        Ok(Err(e)) => return error(StatusCode::BAD_GATEWAY, format!("{name} to robot {robot}: {e}")),
        Err(e) => return error(StatusCode::INTERNAL_SERVER_ERROR, format!("commander failed: {e}")),
    };
    let existing = app.hub.command(&request_id);
    let rec = CommandRecord {
        request_id: request_id.clone(),
        robot,
        name: name.to_string(),
        args: def.args.iter().map(|a| a.name.to_string()).zip(args).collect(),
        sent_ms: existing.as_ref().map_or_else(now_ms, |c| c.sent_ms),
        origin,
        stages: Vec::new(),
    };
    app.hub.tc_sent(rec);
    Json(json!({"request_id": request_id})).into_response()
}

/// What the page's on-board plan buttons send with their control.
#[derive(Deserialize, Default)]
struct OnBoardControl {
    /// Must be true for a control whose TC the MIB marks hazardous (the page asks).
    #[serde(default)]
    confirm: bool,
    /// PLAN_SKIP: the step to skip (0-based); default: the plan's next step as last
    /// reported (the robot refuses any other with PLAN_STEP_MISMATCH).
    #[serde(default)]
    step: Option<u8>,
}

/// Who the command history names as the sender of the panel's TCs.
pub const ONBOARD_ORIGIN: &str = "page: on-board plan";

/// A control TC of a robot's on-board plan, checked against what the collector knows:
/// the robot followed, its link up, its plan in a state the robot accepts the TC in,
/// hazardous TCs confirmed.
async fn onboard_control(
    State(app): State<App>,
    Path((robot, control)): Path<(String, String)>,
    body: axum::body::Bytes,
) -> Response {
    let Some(ctl) = PlanControl::from_word(&control) else {
        let words: Vec<&str> = PlanControl::ALL.iter().map(|c| c.word()).collect();
        return error(
            StatusCode::NOT_FOUND,
            format!(
                "no on-board plan control \"{control}\" (controls: {})",
                words.join(", ")
            ),
        );
    };
    let Ok(robot) = robot.parse::<u8>() else {
        return error(StatusCode::BAD_REQUEST, format!("\"{robot}\" is not a robot number"));
    };
    let req: OnBoardControl = if body.iter().all(u8::is_ascii_whitespace) {
        OnBoardControl::default()
    } else {
        match serde_json::from_slice(&body) {
            Ok(r) => r,
            Err(e) => return error(StatusCode::BAD_REQUEST, format!("POST on-board {}: {e}", ctl.word())),
        }
    };
    let Some(def) = ctl.tc() else {
        return error(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("{} is not in this MIB", ctl.tc_name()),
        );
    };
    match app.hub.link_state(robot) {
        None => {
            return error(
                StatusCode::NOT_FOUND,
                format!("robot {robot} is not followed by this collector"),
            )
        }
        Some(LinkState::Up) => {}
        Some(s) => {
            let s = if s == LinkState::Lost { "lost" } else { "not up yet" };
            return error(
                StatusCode::SERVICE_UNAVAILABLE,
                format!("robot {robot}'s link is {s}: {} not sent", def.name),
            );
        }
    }
    let Some(view) = app.hub.onboard_view(robot) else {
        return error(
            StatusCode::CONFLICT,
            format!(
                "no on-board plan status from robot {robot} yet (HK PLAN or a PLAN event): {} not sent",
                def.name
            ),
        );
    };
    if !ctl.accepted_in(view.state_code) {
        return error(
            StatusCode::CONFLICT,
            format!(
                "{} is accepted only with the plan {}; robot {robot}'s plan is {}",
                def.name,
                ctl.states().join(" or "),
                view.state
            ),
        );
    }
    if let Some(why) = mibinfo::hazard(def) {
        if !req.confirm {
            return error(
                StatusCode::CONFLICT,
                format!("{} is hazardous ({why}): resend with \"confirm\": true", def.name),
            );
        }
    }
    let args = match ctl {
        PlanControl::Skip => vec![i64::from(req.step.unwrap_or(view.done))],
        PlanControl::Suspend | PlanControl::Resume | PlanControl::Abort => Vec::new(),
    };
    if args.len() != def.args.len() {
        return error(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("{} takes {} arguments in this MIB", def.name, def.args.len()),
        );
    }
    dispatch(&app, robot, def, args, ONBOARD_ORIGIN.to_string()).await
}

async fn list_tc(State(app): State<App>) -> Response {
    Json(app.hub.snapshot()["commands"].clone()).into_response()
}

async fn get_tc(State(app): State<App>, Path(id): Path<String>) -> Response {
    match app.hub.command(&id) {
        Some(c) => Json(json!(c)).into_response(),
        None => error(StatusCode::NOT_FOUND, format!("no TC with request ID \"{id}\"")),
    }
}

async fn ack_alarm(State(app): State<App>, Path(id): Path<u64>) -> Response {
    let c = app.commander.clone();
    match tokio::task::spawn_blocking(move || c.ack_alarm(id)).await {
        Ok(Ok(())) => Json(json!({"ok": true})).into_response(),
        Ok(Err(e)) => error(StatusCode::BAD_REQUEST, e.to_string()),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, format!("commander failed: {e}")),
    }
}

#[derive(Deserialize)]
struct Shelve {
    minutes: f64,
}

async fn shelve_alarm(State(app): State<App>, Path(id): Path<u64>, Json(s): Json<Shelve>) -> Response {
    if !(s.minutes.is_finite() && s.minutes > 0.0 && s.minutes <= 7.0 * 24.0 * 60.0) {
        return error(StatusCode::BAD_REQUEST, "shelve: minutes must be in (0, 10080]");
    }
    let c = app.commander.clone();
    let for_ms = (s.minutes * 60_000.0) as i64;
    match tokio::task::spawn_blocking(move || c.shelve_alarm(id, for_ms)).await {
        Ok(Ok(())) => Json(json!({"ok": true})).into_response(),
        Ok(Err(e)) => error(StatusCode::BAD_REQUEST, e.to_string()),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, format!("commander failed: {e}")),
    }
}

async fn plans(State(app): State<App>) -> Response {
    let c = app.commander.clone();
    match tokio::task::spawn_blocking(move || c.plans()).await {
        Ok(p) => Json(json!(p)).into_response(),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, format!("commander failed: {e}")),
    }
}

#[derive(Deserialize)]
struct StartPlan {
    name: String,
    /// Must be true for a plan that sends hazardous TCs (the page asks the operator).
    #[serde(default)]
    confirm: bool,
}

async fn start_plan(
    State(app): State<App>,
    body: Result<Json<StartPlan>, axum::extract::rejection::JsonRejection>,
) -> Response {
    let Json(p) = match body {
        Ok(b) => b,
        Err(e) => return error(StatusCode::BAD_REQUEST, format!("POST /api/plans: {e}")),
    };
    let c = app.commander.clone();
    match tokio::task::spawn_blocking(move || c.start_plan(&p.name, p.confirm)).await {
        Ok(Ok(run_id)) => Json(json!({"run_id": run_id})).into_response(),
        Ok(Err(e)) => {
            let status = match &e {
                PlanStartError::Unknown(_) => StatusCode::NOT_FOUND,
                PlanStartError::Busy(_) | PlanStartError::NeedsConfirmation(_) => StatusCode::CONFLICT,
                PlanStartError::Refused(_) => StatusCode::BAD_REQUEST,
            };
            error(status, e.to_string())
        }
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, format!("commander failed: {e}")),
    }
}

#[derive(Deserialize)]
struct SeriesQuery {
    robot: u8,
    param: String,
    t0: i64,
    t1: i64,
    columns: usize,
}

async fn series(State(app): State<App>, Query(q): Query<SeriesQuery>) -> Response {
    let Some(p) = mib::params::by_name(&q.param) else {
        return error(
            StatusCode::NOT_FOUND,
            format!("no parameter named \"{}\" in the MIB", q.param),
        );
    };
    if q.t1 <= q.t0 {
        return error(StatusCode::BAD_REQUEST, "series: t1 must be after t0");
    }
    let columns = q.columns.clamp(1, MAX_COLUMNS);
    let (robot, name, t0, t1) = (q.robot, p.name, q.t0, q.t1);
    let archive = app.series.clone();
    let archived = match tokio::task::spawn_blocking(move || archive.decimate(robot, name, t0, t1, columns)).await {
        Ok(a) => a,
        Err(e) => return error(StatusCode::INTERNAL_SERVER_ERROR, format!("archive query failed: {e}")),
    };
    let live = app.hub.live_samples(robot, name, t0, t1);
    let (live_cols, skipped) = super::decimate(&live, t0, t1, columns);
    // Min/max merge is exact even where archive and live overlap.
    let mut cols: BTreeMap<i64, (f64, f64)> = BTreeMap::new();
    for (t, lo, hi) in archived.into_iter().chain(live_cols) {
        if !(lo.is_finite() && hi.is_finite()) {
            continue;
        }
        let e = cols.entry(t).or_insert((lo, hi));
        e.0 = e.0.min(lo);
        e.1 = e.1.max(hi);
    }
    let points: Vec<Value> = cols.into_iter().map(|(t, (lo, hi))| json!([t, lo, hi])).collect();
    Json(
        json!({"robot": robot, "param": name, "unit": p.unit, "t0": t0, "t1": t1, "columns": columns,
        "points": points, "skipped_non_finite": skipped,
        "limits": p.limits.map(|l| json!([l.soft_lo, l.soft_hi, l.hard_lo, l.hard_hi]))}),
    )
    .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: GND-15
    #[test]
    fn only_loopback_hosts_pass_without_a_token() {
        assert!(loopback_host("127.0.0.1:8080"));
        assert!(loopback_host("localhost"));
        assert!(loopback_host("[::1]:80"));
        assert!(!loopback_host("evil.example:8080"));
        assert!(!loopback_host("10.0.0.5:8080"));
    }

    // verifies: GND-15
    #[test]
    fn binding_elsewhere_needs_a_token() {
        let any: SocketAddr = "0.0.0.0:8080".parse().unwrap();
        let lo: SocketAddr = "127.0.0.1:8080".parse().unwrap();
        assert!(matches!(check_binding(any, &None), Err(ServeError::TokenRequired(_))));
        assert!(check_binding(any, &Some("t".into())).is_ok());
        assert!(check_binding(lo, &None).is_ok());
    }
}
