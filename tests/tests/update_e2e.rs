//! Software update end to end (docs/update.md): the real `ground update` and `ground file`
//! verbs against the real `obsw` started by the boot launcher `obsw-boot`, over the space
//! link (SDLS, COP-1) on loopback UDP. A new image goes up by CFDP, is installed and
//! activated; the launcher restarts into it, it confirms after its self-test and reports its
//! version in HK UPDATE. An image with a bad signature, a truncated image and a repeated
//! activation are refused, counted and evented. A broken image (its start file injects a
//! self-test failure) resets unconfirmed and the launcher rolls back. Judged from what the
//! robot sent (`--tm-log`) and the ground's verification output.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use e2e_tests::{bin, free_udp, Tm};
use mib::events::eid;
use mib::params::pid;
use mib::FailureCode as F;

struct Dir(PathBuf);

impl Dir {
    fn s(&self, f: &str) -> String {
        self.0.join(f).display().to_string()
    }
}

impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The launcher's process (the obsw replaces it, and itself at each reset: one PID).
struct Robot {
    child: Child,
    ready: mpsc::Receiver<String>,
}

impl Robot {
    /// Waits for the next READY line of a (re)started obsw.
    fn ready(&self, limit: Duration) -> String {
        self.ready.recv_timeout(limit).expect("the obsw printed READY")
    }
}

impl Drop for Robot {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(2) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

struct Setup {
    d: Dir,
    robot: SocketAddr,
    listen: SocketAddr,
}

impl Setup {
    fn ground(&self, args: &[&str]) -> Output {
        Command::new(bin("ground"))
            .arg("--no-archive")
            .args(args)
            .current_dir(&self.d.0)
            .env("MMIC_GROUND_LOCK_DIR", self.d.0.join("locks"))
            .output()
            .expect("ground runs")
    }

    /// `ground GROUP VERB --robot … --tm-listen … --keys … ARGS…`.
    fn linked(&self, group: &str, verb: &str, args: &[&str]) -> Output {
        let (robot, listen, keys) = (
            format!("1={}", self.robot),
            format!("1={}", self.listen),
            self.d.s("keys"),
        );
        let mut all = vec![group, verb, "--robot", &robot, "--tm-listen", &listen, "--keys", &keys];
        all.extend_from_slice(args);
        self.ground(&all)
    }

    /// Every TM packet the running obsw sent since it started.
    fn tm(&self) -> Vec<Tm> {
        let text = std::fs::read_to_string(self.d.0.join("tm.log")).unwrap_or_default();
        text.lines()
            .filter_map(|l| {
                let b: Option<Vec<u8>> = (0..l.len())
                    .step_by(2)
                    .map(|i| l.get(i..i + 2).and_then(|h| u8::from_str_radix(h, 16).ok()))
                    .collect();
                // A line being written is not a whole packet yet (the header's length says).
                let b = b?;
                let whole = b.len() >= 6 && b.len() == 7 + usize::from(u16::from_be_bytes([b[4], b[5]]));
                // Only PUS TM (the CFDP APID's PDU packets have no secondary header, and
                // spacepackets 0.17's reader panics on a packet shorter than a PUS header).
                let pus = b.len() >= 22 && b[0] & 0x08 != 0;
                let whole = whole && pus;
                whole.then(|| Tm::parse(&b)).flatten()
            })
            .collect()
    }

    /// Waits until the log holds an HK UPDATE report satisfying `want`; the last such report.
    fn hk_until(&self, limit: Duration, want: impl Fn(&Tm) -> bool) -> Tm {
        let t0 = Instant::now();
        loop {
            let hk = self
                .tm()
                .into_iter()
                .filter(|t| t.sid() == Some(mib::hk::sid::UPDATE))
                .rfind(&want);
            if let Some(h) = hk {
                return h;
            }
            assert!(t0.elapsed() < limit, "no HK UPDATE as expected within {limit:?}");
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    fn events(&self, id: u16) -> usize {
        self.tm().iter().filter(|t| t.event_id() == Some(id)).count()
    }
}

fn ok(o: &Output) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success(),
        "exit {:?}\nstdout: {out}\nstderr: {}",
        o.status.code(),
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

fn refused(o: &Output, code: &str) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(!o.status.success(), "refused expected: {out}");
    assert!(
        out.contains(code),
        "{code} expected in: {out}\nstderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

/// A start file for the launcher: the obsw binary, with `env` set first.
fn start_file(d: &Dir, name: &str, env: &str) -> String {
    let p = d.s(name);
    std::fs::write(
        &p,
        format!("#!/bin/sh\n# {name}\nexec env {env} {} \"$@\"\n", bin("obsw").display()),
    )
    .unwrap();
    p
}

// verifies: UPD-E2E-01, UPD-OTA-02, UPD-IMG-02, UPD-SVC-01, UPD-SVC-02
#[test]
fn an_image_goes_up_activates_confirms_and_a_broken_one_rolls_back_while_bad_ones_are_refused() {
    let t_start = Instant::now();
    let d = Dir(std::env::temp_dir().join(format!("update-e2e-{}", std::process::id())));
    let _ = std::fs::remove_dir_all(&d.0);
    std::fs::create_dir_all(&d.0).unwrap();
    let (frame, listen) = (free_udp(), free_udp());
    let s = Setup {
        d,
        robot: frame,
        listen,
    };
    ok(&s.ground(&["keys", "create", &s.d.s("keys"), "--robot", "1"]));
    ok(&s.ground(&["update", "keygen", &s.d.s("signing")]));
    let key = s.d.s("signing/update.key");
    let sign = |version: &str, payload: &str, out: &str| {
        ok(&s.ground(&[
            "update",
            "sign",
            "--key",
            &key,
            "--version",
            version,
            "--target",
            "host",
            payload,
            &s.d.s(out),
        ]));
    };
    sign("1.0.0", &start_file(&s.d, "v1.sh", "MMIC_VERSION=1"), "v1.img");
    sign("2.0.0", &start_file(&s.d, "v2.sh", "MMIC_VERSION=2"), "v2.img");
    sign("3.0.0", &start_file(&s.d, "v3.sh", "OBSW_SELF_TEST_FAIL=1"), "v3.img");
    let v2 = std::fs::read(s.d.s("v2.img")).unwrap();
    let mut bad = v2.clone();
    bad[60] ^= 0x01; // a byte of the signature
    std::fs::write(s.d.s("bad.img"), &bad).unwrap();
    std::fs::write(s.d.s("short.img"), &v2[..v2.len() - 10]).unwrap();

    let (fr, tt) = (frame.to_string(), listen.to_string());
    let mut child = Command::new(bin("obsw-boot"))
        .args(["--slots", &s.d.s("slots"), "--update-key", &s.d.s("signing/update.pub")])
        .args(["--init", &s.d.s("v1.img"), "--"])
        .args([
            "--robot",
            "1",
            "--udp",
            "127.0.0.1:0",
            "--tcp",
            "127.0.0.1:0",
            "--sim-ctl",
            "127.0.0.1:0",
        ])
        .args(["--keys", &s.d.s("keys"), "--frame-udp", &fr, "--frame-tm-to", &tt])
        .args(["--files", &s.d.s("robot-files"), "--tm-log", &s.d.s("tm.log")])
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(s.d.0.join("robot.log")).unwrap())
        .spawn()
        .expect("obsw-boot starts");
    let (tx, rx) = mpsc::channel();
    let out = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if line.starts_with("READY") && tx.send(line).is_err() {
                return;
            }
        }
    });
    let robot = Robot { child, ready: rx };
    robot.ready(Duration::from_secs(20));
    let h = s.hk_until(Duration::from_secs(12), |_| true);
    assert_eq!((h.hk(pid::SW_VERSION), h.hk(pid::SW_SLOT)), (Some(0x010000), Some(0)));

    // Version 2 up over CFDP, installed and activated.
    for f in ["v2.img", "bad.img", "short.img", "v3.img"] {
        ok(&s.linked("file", "put", &[&s.d.s(f)]));
    }
    // An activation before anything is installed names nothing.
    refused(
        &s.linked("update", "activate", &[&s.d.s("v2.img"), "--confirm"]),
        F::UPDATE_NOT_INSTALLED.name(),
    );
    // A confirmation with nothing waiting for one.
    let (robot_arg, listen_arg, keys_arg) = (format!("1={}", s.robot), format!("1={}", s.listen), s.d.s("keys"));
    refused(
        &s.ground(&[
            "send",
            "--robot",
            &robot_arg,
            "--tm-listen",
            &listen_arg,
            "--keys",
            &keys_arg,
            "UPDATE_CONFIRM",
        ]),
        F::UPDATE_NOTHING_TO_CONFIRM.name(),
    );
    for (img, why) in [("bad.img", "SIGNATURE"), ("short.img", "TRUNCATED")] {
        let out = refused(&s.linked("update", "install", &[img]), why);
        assert!(out.contains(F::UPDATE_IMAGE_REFUSED.name()), "{out}");
    }
    ok(&s.linked("update", "install", &["v2.img"]));
    let h = s.hk_until(Duration::from_secs(12), |h| {
        h.hk(pid::UPDATE_INSTALLED_VERSION) == Some(0x020000)
    });
    assert_eq!(h.hk(pid::UPDATE_REFUSALS), Some(4));
    assert_eq!(s.events(eid::UPDATE_REFUSED), 2, "each refused image evented");
    ok(&s.linked("update", "activate", &[&s.d.s("v2.img"), "--confirm"]));
    robot.ready(Duration::from_secs(20));
    let h = s.hk_until(Duration::from_secs(12), |h| h.hk(pid::SW_VERSION) == Some(0x020000));
    assert_eq!(h.hk(pid::SW_SLOT), Some(1));
    assert_eq!(
        h.hk(pid::UPDATE_OUTCOME),
        Some(i64::from(mib::update::outcome::CONFIRMED))
    );
    assert_eq!(s.events(eid::UPDATE_CONFIRMED), 1);

    // The same activation again: the image it names already runs.
    refused(
        &s.linked("update", "activate", &[&s.d.s("v2.img"), "--confirm"]),
        F::UPDATE_STALE_ACTIVATION.name(),
    );
    assert!(s.tm().iter().any(|t| t.event_id() == Some(eid::TC_REJECTED)));

    // Version 3 fails its self-test: it resets unconfirmed, and version 2 comes back.
    ok(&s.linked("update", "install", &["v3.img"]));
    // An activation written for another image than the one installed.
    refused(
        &s.linked("update", "activate", &[&s.d.s("v1.img"), "--confirm"]),
        F::UPDATE_WRONG_IMAGE.name(),
    );
    // The inactive slot changed after its install (a byte of the payload flipped on the
    // slot's medium): the activation checks it again and refuses; put back, it goes on.
    let slot = s.d.0.join("slots/ota_0");
    let flip = |slot: &std::path::Path| {
        use std::os::unix::fs::FileExt;
        let f = std::fs::OpenOptions::new().read(true).write(true).open(slot).unwrap();
        let mut b = [0u8; 1];
        f.read_exact_at(&mut b, 130).unwrap();
        f.write_all_at(&[b[0] ^ 0x01], 130).unwrap();
    };
    flip(&slot);
    refused(
        &s.linked("update", "activate", &[&s.d.s("v3.img"), "--confirm"]),
        F::UPDATE_SLOT_CHANGED.name(),
    );
    flip(&slot);
    ok(&s.linked("update", "activate", &[&s.d.s("v3.img"), "--confirm"]));
    // Version 3 resets before or after its READY (module discovery may not be done when
    // its self-test fails); version 2's READY follows. HK of the running obsw decides.
    robot.ready(Duration::from_secs(20));
    let h = s.hk_until(Duration::from_secs(30), |h| {
        h.hk(pid::UPDATE_OUTCOME) == Some(i64::from(mib::update::outcome::ROLLED_BACK))
    });
    assert_eq!((h.hk(pid::SW_VERSION), h.hk(pid::SW_SLOT)), (Some(0x020000), Some(1)));
    assert_eq!(s.events(eid::UPDATE_ROLLED_BACK), 1);
    eprintln!("update e2e: {:.1} s", t_start.elapsed().as_secs_f64());
    drop(robot);
}
