//! The dashboard's HTTP API over a real socket: the TC round trip, stages, hazardous
//! confirmation, the event stream's resume after a reconnect and its reset, access
//! control, and plots merging archive and live data. The hub is fed by hand (the
//! browser test in `ground/web/test/e2e.mjs` feeds it from real obsw processes).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ground::dashboard::{
    self, AlarmRecord, AlarmState, CommandError, Commander, Hub, PlanInfo, PlanStartError, Series, Stage, StageReport,
};
use serde_json::{json, Value};

/// Records what the page asked for; answers with sequential request IDs.
#[derive(Default)]
struct Recorder {
    sent: Mutex<Vec<(u8, String, Vec<i64>)>>,
    acked: Mutex<Vec<u64>>,
}

impl Commander for Recorder {
    fn send_tc(&self, robot: u8, name: &str, args: &[i64]) -> Result<String, CommandError> {
        let mut s = self.sent.lock().unwrap();
        s.push((robot, name.to_string(), args.to_vec()));
        Ok(format!("{robot}-test-{}", s.len()))
    }
    fn ack_alarm(&self, id: u64) -> Result<(), CommandError> {
        self.acked.lock().unwrap().push(id);
        Ok(())
    }
    fn shelve_alarm(&self, id: u64, _: i64) -> Result<(), CommandError> {
        Err(CommandError(format!("alarm {id} cannot be shelved here")))
    }
    fn plans(&self) -> Vec<PlanInfo> {
        vec![PlanInfo {
            name: "demo".into(),
            description: "d".into(),
            robots: vec![1],
            steps: 1,
            hazards: Vec::new(),
        }]
    }
    fn start_plan(&self, name: &str, _confirmed: bool) -> Result<String, PlanStartError> {
        Ok(format!("{name}-1"))
    }
}

/// An archive holding one sample per second from t = 0 to 99 s, value = t.
struct Archive;
impl Series for Archive {
    fn decimate(&self, _robot: u8, _param: &str, t0: i64, t1: i64, columns: usize) -> Vec<(i64, f64, f64)> {
        let s: Vec<(i64, f64)> = (0..100).map(|i| (i * 1000, i as f64)).collect();
        dashboard::decimate(&s, t0, t1, columns).0
    }
}

fn start(token: Option<&str>, hub: Hub) -> (dashboard::Running, Arc<Recorder>) {
    let rec = Arc::new(Recorder::default());
    let r = dashboard::spawn(
        "127.0.0.1:0".parse().unwrap(),
        token.map(str::to_string),
        hub,
        rec.clone(),
        Arc::new(Archive),
    )
    .expect("server starts");
    (r, rec)
}

/// One HTTP/1.1 request; returns (status, body).
fn http(addr: SocketAddr, method: &str, path: &str, headers: &[(&str, &str)], body: Option<Value>) -> (u16, String) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let body = body.map(|b| b.to_string()).unwrap_or_default();
    let mut req = format!(
        "{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\nContent-Length: {}\r\n",
        body.len()
    );
    if !body.is_empty() {
        req.push_str("Content-Type: application/json\r\n");
    }
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    req.push_str(&body);
    s.write_all(req.as_bytes()).unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).unwrap();
    let status = out[9..12].parse().unwrap();
    let body = out.split_once("\r\n\r\n").map(|x| x.1.to_string()).unwrap_or_default();
    // Bodies of JSON answers are small and sent with Content-Length by axum.
    (status, body)
}

fn json_of(body: &str) -> Value {
    serde_json::from_str(body).unwrap_or_else(|e| panic!("not JSON ({e}): {body}"))
}

/// Opens the event stream and returns the IDs of the first `n` messages.
fn stream_ids(addr: SocketAddr, query: &str, last_event_id: Option<u64>, n: usize) -> (Vec<u64>, Vec<String>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut req = format!("GET /api/stream{query} HTTP/1.1\r\nHost: localhost\r\n");
    if let Some(id) = last_event_id {
        req.push_str(&format!("Last-Event-ID: {id}\r\n"));
    }
    req.push_str("\r\n");
    s.write_all(req.as_bytes()).unwrap();
    let mut r = BufReader::new(s);
    let (mut ids, mut kinds) = (Vec::new(), Vec::new());
    let mut line = String::new();
    while ids.len() + kinds.iter().filter(|k| *k == "reset").count() < n {
        line.clear();
        if r.read_line(&mut line).unwrap() == 0 {
            break;
        }
        // Chunked transfer: chunk-size lines are hex only and never start with a field name.
        if let Some(id) = line.trim().strip_prefix("id: ") {
            ids.push(id.parse().unwrap());
        }
        if let Some(ev) = line.trim().strip_prefix("event: ") {
            kinds.push(ev.to_string());
        }
    }
    (ids, kinds)
}

// verifies: GND-18, PUS-17-01
#[test]
fn ping_round_trip_returns_a_request_id_and_its_stages() {
    let hub = Hub::new();
    let (srv, rec) = start(None, hub.clone());
    let (st, body) = http(
        srv.local_addr(),
        "POST",
        "/api/tc",
        &[],
        Some(json!({"robot": 1, "name": "PING", "args": {}})),
    );
    assert_eq!(st, 200, "{body}");
    let id = json_of(&body)["request_id"].as_str().unwrap().to_string();
    assert_eq!(rec.sent.lock().unwrap()[0], (1, "PING".to_string(), vec![]));
    for stage in [Stage::Acceptance, Stage::Completion] {
        hub.tc_stage(
            1,
            &id,
            StageReport {
                stage,
                step: None,
                t_ms: 1,
                success: true,
                failure: None,
            },
        );
    }
    let (st, body) = http(srv.local_addr(), "GET", &format!("/api/tc/{id}"), &[], None);
    assert_eq!(st, 200);
    let v = json_of(&body);
    assert_eq!(v["name"], "PING");
    assert_eq!(v["origin"], "page");
    assert_eq!(v["stages"][0]["stage"], "acceptance");
    assert_eq!(v["stages"][0]["success"], true);
    assert_eq!(v["stages"][1]["stage"], "completion");
    assert_eq!(http(srv.local_addr(), "GET", "/api/tc/nope", &[], None).0, 404);
}

// verifies: GND-18, PUS-8-02
#[test]
fn arguments_are_checked_and_hazardous_tcs_need_confirmation() {
    let (srv, rec) = start(None, Hub::new());
    let a = srv.local_addr();
    let bad = json!({"robot": 1, "name": "RECONFIGURE", "args": {"from": 0, "to": 200}});
    let (st, body) = http(a, "POST", "/api/tc", &[], Some(bad));
    assert_eq!(st, 400);
    assert!(body.contains("outside"), "{body}");
    let (st, body) = http(a, "POST", "/api/tc", &[], Some(json!({"robot": 1, "name": "NOPE"})));
    assert_eq!(st, 400);
    assert!(body.contains("no TC named"), "{body}");
    let mode = json!({"robot": 1, "name": "MODE_SET", "args": {"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}});
    let (st, body) = http(a, "POST", "/api/tc", &[], Some(mode.clone()));
    assert_eq!(st, 409, "{body}");
    assert!(body.contains("hazardous"), "{body}");
    assert!(rec.sent.lock().unwrap().is_empty(), "nothing sent before confirmation");
    let mut confirmed = mode;
    confirmed["confirm"] = json!(true);
    assert_eq!(http(a, "POST", "/api/tc", &[], Some(confirmed)).0, 200);
    assert_eq!(rec.sent.lock().unwrap()[0].2, vec![1, 1, 0]);
}

// verifies: GND-16
#[test]
fn event_stream_resumes_from_last_event_id_and_resets_when_too_far_behind() {
    let hub = Hub::with_capacity(50, 16);
    let (srv, _) = start(None, hub.clone());
    for i in 0..20 {
        hub.hk(1, i, &[("V_BAT_A", 12.0)]);
    }
    // A page that saw up to 12 reconnects: gets 13..=20, then live 21, 22.
    let h = hub.clone();
    let feeder = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(300));
        h.hk(1, 100, &[("V_BAT_A", 12.0)]);
        h.hk(1, 101, &[("V_BAT_A", 12.0)]);
    });
    let (ids, _) = stream_ids(srv.local_addr(), "", Some(12), 10);
    feeder.join().unwrap();
    assert_eq!(ids, (13..=22).collect::<Vec<u64>>());
    // `since` works the same for the first connection after a snapshot.
    let (ids, _) = stream_ids(srv.local_addr(), "?since=18", None, 4);
    assert_eq!(ids, vec![19, 20, 21, 22]);
    // Push the old messages out of the ring: a client at 5 must reload.
    for i in 0..60 {
        hub.hk(1, 200 + i, &[("V_BAT_A", 12.0)]);
    }
    let (ids, kinds) = stream_ids(srv.local_addr(), "", Some(5), 1);
    assert!(ids.is_empty());
    assert_eq!(kinds, vec!["reset".to_string()]);
    assert_eq!(hub.stats().resets, 1);
}

// verifies: GND-15
#[test]
fn a_token_guards_the_api_and_commanding() {
    let (srv, rec) = start(Some("s3cret"), Hub::new());
    let a = srv.local_addr();
    let ping = json!({"robot": 1, "name": "PING", "args": {}});
    assert_eq!(http(a, "POST", "/api/tc", &[], Some(ping.clone())).0, 401);
    assert_eq!(
        http(
            a,
            "POST",
            "/api/tc",
            &[("Authorization", "Bearer wrong")],
            Some(ping.clone())
        )
        .0,
        401
    );
    assert_eq!(http(a, "GET", "/api/snapshot", &[], None).0, 401);
    assert!(rec.sent.lock().unwrap().is_empty());
    assert_eq!(
        http(a, "POST", "/api/tc", &[("Authorization", "Bearer s3cret")], Some(ping)).0,
        200
    );
    assert_eq!(http(a, "GET", "/api/snapshot?token=s3cret", &[], None).0, 200);
    // The page itself carries no data and loads without the token.
    assert_eq!(http(a, "GET", "/", &[], None).0, 200);
    // Without a token the server refuses to bind beyond loopback.
    let err = dashboard::spawn(
        "0.0.0.0:0".parse().unwrap(),
        None,
        Hub::new(),
        Arc::new(Recorder::default()),
        Arc::new(dashboard::NoArchive),
    );
    assert!(matches!(err, Err(dashboard::ServeError::TokenRequired(_))));
}

// verifies: GND-15
#[test]
fn without_a_token_only_loopback_host_names_are_answered() {
    let (srv, _) = start(None, Hub::new());
    let (st, _) = http(srv.local_addr(), "GET", "/api/snapshot", &[], None);
    assert_eq!(st, 200);
    // DNS rebinding: a page from another site that resolved its name to 127.0.0.1.
    let mut s = TcpStream::connect(srv.local_addr()).unwrap();
    s.write_all(b"GET /api/snapshot HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n")
        .unwrap();
    let mut out = String::new();
    s.read_to_string(&mut out).unwrap();
    assert!(out.starts_with("HTTP/1.1 403"), "{out}");
}

// verifies: GND-18, GND-13
#[test]
fn alarms_are_acknowledged_through_the_commander() {
    let hub = Hub::new();
    let (srv, rec) = start(None, hub.clone());
    hub.alarm(AlarmRecord {
        id: 7,
        robot: 2,
        source: "V_BAT_A".into(),
        severity: "high".into(),
        state: AlarmState::Active,
        message: "low".into(),
        first_ms: 1,
        last_ms: 1,
        shelved_until_ms: None,
    });
    assert_eq!(http(srv.local_addr(), "POST", "/api/alarms/7/ack", &[], None).0, 200);
    assert_eq!(*rec.acked.lock().unwrap(), vec![7]);
    let (st, body) = http(
        srv.local_addr(),
        "POST",
        "/api/alarms/7/shelve",
        &[],
        Some(json!({"minutes": 10})),
    );
    assert_eq!(st, 400);
    assert!(body.contains("cannot be shelved"), "{body}");
    let snap = json_of(&http(srv.local_addr(), "GET", "/api/snapshot", &[], None).1);
    assert_eq!(snap["alarms"][0]["source"], "V_BAT_A");
}

// verifies: GND-17
#[test]
fn plots_merge_archive_and_live_samples_per_column() {
    let hub = Hub::new();
    let (srv, _) = start(None, hub.clone());
    // Live data continues the archive (100 s … 119 s), with one outlier.
    for i in 100..120 {
        let v = if i == 110 { 1.0e6 } else { i as f64 };
        hub.hk(3, i * 1000, &[("V_BAT_A", v)]);
    }
    let (st, body) = http(
        srv.local_addr(),
        "GET",
        "/api/series?robot=3&param=V_BAT_A&t0=0&t1=120000&columns=12",
        &[],
        None,
    );
    assert_eq!(st, 200, "{body}");
    let v = json_of(&body);
    let pts = v["points"].as_array().unwrap();
    assert_eq!(pts.len(), 12, "every column drawn: {pts:?}");
    assert_eq!(pts[0], json!([0, 0.0, 9.0]));
    assert_eq!(
        pts[11],
        json!([110000, 111.0, 1.0e6]),
        "the outlier is a spike in its column only"
    );
    assert_eq!(pts[10], json!([100000, 100.0, 109.0]));
    assert_eq!(v["unit"], "V");
    let (st, _) = http(
        srv.local_addr(),
        "GET",
        "/api/series?robot=3&param=NOPE&t0=0&t1=1&columns=1",
        &[],
        None,
    );
    assert_eq!(st, 404);
}

// verifies: GND-15
#[test]
fn the_page_is_served_from_the_binary() {
    let (srv, _) = start(None, Hub::new());
    let (st, html) = http(srv.local_addr(), "GET", "/", &[], None);
    assert_eq!(st, 200);
    assert!(html.contains("app.js"));
    let (st, js) = http(srv.local_addr(), "GET", "/app.js", &[], None);
    assert_eq!(st, 200);
    assert!(js.len() > 10_000, "bundle with uPlot");
    let mib = json_of(&http(srv.local_addr(), "GET", "/api/mib", &[], None).1);
    let ping = mib["tcs"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["name"] == "PING")
        .cloned();
    assert_eq!(ping.unwrap()["hazard"], Value::Null);
}

// verifies: GND-16
#[test]
fn stop_returns_with_an_event_stream_open() {
    let (srv, _) = start(None, Hub::new());
    let mut s = TcpStream::connect(srv.local_addr()).unwrap();
    s.write_all(b"GET /api/stream HTTP/1.1\r\nHost: localhost\r\n\r\n")
        .unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut first = [0u8; 12];
    s.read_exact(&mut first).unwrap();
    assert_eq!(&first, b"HTTP/1.1 200");
    let t = std::time::Instant::now();
    srv.stop();
    assert!(t.elapsed() < Duration::from_secs(5), "stop took {:?}", t.elapsed());
}

// verifies: GND-ONBOARD-01, GND-ONBOARD-02
#[test]
fn on_board_plan_controls_are_checked_against_robot_link_and_plan_state() {
    use mib::params::pid;
    use mib::plan::state;
    let hub = Hub::new();
    let (srv, rec) = start(None, hub.clone());
    let a = srv.local_addr();
    let post = |path: &str, body: Option<Value>| {
        let (st, b) = http(a, "POST", path, &[], body);
        (st, json_of(&b)["error"].as_str().unwrap_or("").to_string(), b)
    };
    // Neither a control nor a robot the collector knows.
    let (st, e, _) = post("/api/robots/1/onboard/start", None);
    assert_eq!(st, 404);
    assert!(e.contains("suspend, resume, abort, skip"), "{e}");
    let (st, e, _) = post("/api/robots/1/onboard/suspend", None);
    assert_eq!(st, 404);
    assert!(e.contains("robot 1 is not followed"), "{e}");
    // Followed, link not up: the TC would not arrive.
    hub.add_robot(1);
    let (st, e, _) = post("/api/robots/1/onboard/suspend", None);
    assert_eq!(st, 503);
    assert!(e.contains("link is not up yet"), "{e}");
    hub.link(1, dashboard::LinkState::Lost);
    assert!(post("/api/robots/1/onboard/suspend", None).1.contains("link is lost"));
    hub.heard(1, 1);
    // Up, but no plan status heard yet.
    let (st, e, _) = post("/api/robots/1/onboard/suspend", None);
    assert_eq!(st, 409);
    assert!(e.contains("no on-board plan status"), "{e}");
    // A running plan, from its HK; the snapshot and the stream carry it.
    let id0 = hub.last_id();
    let hk = [
        (pid::PLAN_STATE, i64::from(state::RUNNING)),
        (pid::PLAN_ID, 0xA1B2_C3D4),
        (pid::PLAN_STEPS, 4),
        (pid::PLAN_NEXT_STEP, 1),
        (pid::PLAN_DONE, 1),
        (pid::PLAN_WAIT_ROBOT, 0),
        (pid::PLAN_WAIT_STEP, 0),
    ];
    hub.onboard(1, |p| p.apply_hk(10, &hk));
    let (st, body) = http(a, "GET", "/api/snapshot", &[], None);
    assert_eq!(st, 200);
    let ob = &json_of(&body)["robots"][0]["onboard"];
    assert_eq!(
        (
            ob["state"].as_str(),
            ob["plan_id"].as_str(),
            ob["steps"].as_u64(),
            ob["done"].as_u64()
        ),
        (Some("RUNNING"), Some("0xa1b2c3d4"), Some(4), Some(1)),
        "{ob}"
    );
    assert_eq!(ob["controls"], json!(["suspend", "abort"]));
    let (ids, _) = stream_ids(a, &format!("?since={id0}"), None, 1);
    assert_eq!(ids, vec![id0 + 1], "one stream message for the change");
    // Only the controls the robot accepts in RUNNING are sent.
    for c in ["resume", "skip"] {
        let (st, e, _) = post(&format!("/api/robots/1/onboard/{c}"), Some(json!({"confirm": true})));
        assert_eq!(st, 409, "{c}: {e}");
        assert!(
            e.contains("only with the plan SUSPENDED") && e.contains("RUNNING"),
            "{e}"
        );
    }
    assert!(rec.sent.lock().unwrap().is_empty(), "nothing sent yet");
    let (st, _, body) = post("/api/robots/1/onboard/suspend", None);
    assert_eq!(st, 200, "{body}");
    let id = json_of(&body)["request_id"].as_str().unwrap().to_string();
    assert_eq!(rec.sent.lock().unwrap()[0], (1, "PLAN_SUSPEND".to_string(), vec![]));
    let c = hub.command(&id).expect("in the command history");
    assert_eq!(
        (c.name.as_str(), c.origin.as_str()),
        ("PLAN_SUSPEND", "page: on-board plan")
    );
    // The robot reports SUSPENDED (event): RESUME is hazardous in the MIB and needs the
    // operator's confirmation; SKIP takes the plan's next step.
    hub.onboard(1, |p| {
        p.apply_event(20, mib::events::eid::PLAN_STATE_CHANGED, |k| match k {
            "state" => Some(i64::from(state::SUSPENDED)),
            "step" => Some(2),
            "cause" => Some(i64::from(mib::plan::cause::COMMAND)),
            "plan_id" => Some(0xA1B2_C3D4),
            _ => None,
        })
    });
    let (st, e, _) = post("/api/robots/1/onboard/resume", None);
    assert_eq!(st, 409);
    assert!(e.contains("PLAN_RESUME is hazardous"), "{e}");
    assert_eq!(post("/api/robots/1/onboard/suspend", None).0, 409, "already suspended");
    assert_eq!(
        post("/api/robots/1/onboard/resume", Some(json!({"confirm": true}))).0,
        200
    );
    assert_eq!(
        post("/api/robots/1/onboard/skip", Some(json!({"confirm": true}))).0,
        200
    );
    assert_eq!(post("/api/robots/1/onboard/abort", Some(json!({}))).0, 200);
    let (st, e, _) = post("/api/robots/1/onboard/abort", Some(json!({"confirm": "yes"})));
    assert_eq!(st, 400, "{e}");
    let sent: Vec<(String, Vec<i64>)> = rec.sent.lock().unwrap()[1..]
        .iter()
        .map(|(_, n, a)| (n.clone(), a.clone()))
        .collect();
    assert_eq!(
        sent,
        vec![
            ("PLAN_RESUME".to_string(), vec![]),
            ("PLAN_SKIP".to_string(), vec![2]),
            ("PLAN_ABORT".to_string(), vec![])
        ]
    );
}
