//! The collector configuration's tests: parsing, defaults, located errors.

use super::*;

// verifies: GND-11
#[test]
fn a_full_config_reads() {
    let c = parse(
        "c.toml",
        r#"
transport = "lab-udp"
retain = "30d"
[link]
loss_timeout_ms = 4000
max_backoff_ms = 2000
[gaps]
retry_ms = 2000
max_tries = 4
[alarms]
stale_hk_intervals = 3
event_min_severity = "high"
[[robot]]
number = 1
addr = "127.0.0.1:9001"
hk_interval_ms = 100
[[robot]]
number = 2
transport = "lab-tcp"
"#,
    )
    .unwrap();
    assert_eq!(c.robots.len(), 2);
    assert_eq!(c.robots[0].addr, "127.0.0.1:9001".parse().unwrap());
    assert_eq!(c.robots[1].transport, Transport::Tcp);
    assert_eq!(c.robots[1].addr, default_addr(2, Transport::Tcp));
    assert_eq!(c.retain_ms, Some(30 * 86_400_000));
    assert_eq!(c.max_backoff_ms, 2000);
    assert_eq!(c.event_min_severity, mib::events::Severity::High);
    // The link-loss rule of every front end, with the configured floor.
    let loss = |hk| {
        crate::tracker::LinkWatch::new(hk, 0)
            .with_floor(c.loss_timeout_ms)
            .loss_after_ms()
    };
    assert_eq!(loss(1000), 4000);
    assert_eq!(loss(2000), 5000);
}

// verifies: OPS-LINK-DEFAULT-01
#[test]
fn robots_use_the_space_link_unless_a_lab_link_is_named_and_local() {
    let e = parse("c.toml", "[[robot]]\nnumber = 1\n").unwrap_err().to_string();
    assert!(e.contains("robot 1 over frames: the file needs keys"), "{e}");
    let c = parse("c.toml", "keys = \"k\"\n[[robot]]\nnumber = 1\n").unwrap();
    assert_eq!(c.robots[0].transport, Transport::Frames);
    let f = c.robots[0].frames.as_ref().unwrap();
    assert_eq!((f.tc_spi, f.tm_security), (1, ground_link::TmSecurity::Encrypt));
    let c = parse(
        "c.toml",
        "keys = \"k\"\ntc_spi = 2\ntm_sdls = \"clear\"\n[[robot]]\nnumber = 1\n",
    )
    .unwrap();
    let f = c.robots[0].frames.as_ref().unwrap();
    assert_eq!((f.tc_spi, f.tm_security), (2, ground_link::TmSecurity::Clear));
    let e = parse("c.toml", "keys = \"k\"\ntc_spi = 3\ntm_sdls = \"open\"\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("c.toml:2:10: tc_spi = 3") && e.contains("c.toml:3:11: tm_sdls"),
        "{e}"
    );
    let e = parse("c.toml", "transport = \"udp\"\n").unwrap_err().to_string();
    assert!(e.contains("\"lab-udp\""), "{e}");
    let e = parse(
        "c.toml",
        "transport = \"lab-udp\"\n[[robot]]\nnumber = 1\naddr = \"10.1.2.3:7301\"\n",
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("c.toml:3:10: robot 1 at 10.1.2.3:7301: a lab link"), "{e}");
}

// verifies: LINK-STREAM-04, GND-11
#[test]
fn a_robot_takes_the_space_link_over_a_serial_line_only_over_frames() {
    let c = parse(
            "cfg/c.toml",
            "keys = \"k\"\n[[robot]]\nnumber = 1\nserial = \"/dev/ttyACM0\"\n[[robot]]\nnumber = 2\nserial = \"sock\"\n[[robot]]\nnumber = 3\n",
        )
        .unwrap();
    let serial = |i: usize| {
        c.robots[i]
            .frames
            .as_ref()
            .map(|f| f.serial.clone())
            .unwrap_or_default()
    };
    assert_eq!(serial(0).get(&1), Some(&PathBuf::from("/dev/ttyACM0")));
    assert_eq!(serial(0).len(), 1);
    // Relative to the file's folder, like keys.
    assert_eq!(serial(1).get(&2), Some(&PathBuf::from("cfg/sock")));
    assert!(serial(2).is_empty(), "robot 3 stays on UDP");
    let e = parse(
            "c.toml",
            "keys = \"k\"\n[[robot]]\nnumber = 1\ntransport = \"lab-udp\"\nserial = \"/dev/a\"\n\
             [[robot]]\nnumber = 2\ntm_listen = \"127.0.0.1:9000\"\nserial = \"/dev/b\"\n[[robot]]\nnumber = 3\nserial = \"\"\n",
        )
        .unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains(
            "c.toml:5:10: robot 1: serial is the space link over a serial line; it does not go with a lab transport"
        ),
        "{text}"
    );
    assert!(
        text.contains("c.toml:9:10: robot 2: serial carries its TM frames too; it does not go with tm_listen"),
        "{text}"
    );
    assert!(
        text.contains("c.toml:12:10: robot 3: the path of the serial device is missing"),
        "{text}"
    );
    assert_eq!(e.errors.len(), 3, "{text}");
}

// verifies: GND-11
#[test]
fn every_error_has_its_line_and_column() {
    let e = parse(
            "c.toml",
            "retain = \"30 days\"\n[link]\nmax_backoff_ms = 9000\n[[robot]]\nnumber = 300\n[[robot]]\nnumber = 1\ntransport = \"x\"\n",
        )
        .unwrap_err();
    let text = e.to_string();
    assert!(text.contains("c.toml:1:10: retain"), "{text}");
    assert!(text.contains("c.toml:3:18: max_backoff_ms"), "{text}");
    assert!(text.contains("c.toml:5:10: robot number 300"), "{text}");
    assert!(text.contains("c.toml:8:13: transport"), "{text}");
    assert_eq!(e.errors.len(), 4);
}

// verifies: ALM-CFG-01, GND-11
#[test]
fn an_unknown_key_or_a_wrong_type_does_not_hide_the_other_errors() {
    // Issue 26: one unknown key used to be the only error shown of seven.
    let src = "retain = \"30 days\"\nretian = \"1d\"\n[link]\nmax_backoff_ms = 9000\nloss_timeout_ms = \"x\"\n\
                   [alarms]\nlimit = true\n[[robot]]\nnumber = 300\n[[robot]]\nnumber = 1\ntransport = \"x\"\naddres = \"y\"\n\
                   [[robot]]\nname = \"no number\"\n";
    let e = parse("c.toml", src).unwrap_err();
    let text = e.to_string();
    for want in [
        "c.toml:1:10: retain",
        "c.toml:2:1: unknown field `retian`",
        "c.toml:4:18: max_backoff_ms",
        "c.toml:5:19: invalid type",
        "c.toml:7:1: unknown field `limit`",
        "c.toml:9:10: robot number 300",
        "c.toml:12:13: transport",
        "c.toml:13:1: unknown field `addres`",
        "missing field `number`",
    ] {
        assert!(text.contains(want), "{want:?} not in:\n{text}");
    }
    assert_eq!(e.errors.len(), 9, "{text}");
}

// verifies: ALM-MSG-01
#[test]
fn durations_are_shown_in_the_largest_exact_unit() {
    for s in ["3m", "30d", "12h", "45s", "500ms", "2w", "90m"] {
        assert_eq!(format_duration_ms(parse_duration_ms(s).unwrap()), s);
    }
    assert_eq!(format_duration_ms(parse_duration_ms("36h").unwrap()), "36h");
    assert_eq!(format_duration_ms(parse_duration_ms("7d").unwrap()), "1w");
}

// verifies: GND-11
#[test]
fn unknown_keys_and_bad_toml_are_located() {
    let e = parse("c.toml", "[link]\nloss_timeout = 5\n").unwrap_err();
    assert_eq!((e.errors[0].line, e.errors[0].column), (2, 1));
    assert!(e.errors[0].message.contains("unknown field"), "{}", e);
    let e = parse("c.toml", "[[robot]]\nnumber = 1\nnumber = 2\n").unwrap_err();
    assert_eq!(e.errors[0].line, 3);
    let e = parse("c.toml", "[[robot]]\nnumber = 1\n[[robot]]\nnumber = 1\n").unwrap_err();
    assert!(e.to_string().contains("c.toml:4:10: robot 1 is listed twice"));
}

// verifies: GND-11, GND-19
#[test]
fn plans_are_checked_and_their_errors_located() {
    let dir = std::env::temp_dir().join(format!("collect-cfg-plans-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
            dir.join("ok.toml"),
            "name = \"ping\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"p\"\nrobot = 1\naction = \"command\"\ntc = \"PING\"\n",
        )
        .unwrap();
    std::fs::write(
        dir.join("bad.toml"),
        "name = \"bad\"\n[[robot]]\nnumber = 1\n[[step]]\nid = \"p\"\nrobot = 1\naction = \"fly\"\n",
    )
    .unwrap();
    let cfg_file = dir.join("c.toml");
    let file = cfg_file.display().to_string();
    let c = parse(&file, "plans = [\"ok.toml\"]\n").unwrap();
    assert_eq!(
        c.plans,
        vec![PlanCfg {
            name: "ping".into(),
            path: dir.join("ok.toml")
        }]
    );
    let e = parse(
        &file,
        "plans = [\"ok.toml\", \"bad.toml\", \"none.toml\", \"ok.toml\"]\n",
    )
    .unwrap_err();
    let text = e.to_string();
    assert_eq!(e.errors.len(), 3, "{text}");
    assert!(
        text.contains(&format!("{file}:1:21: plan {}", dir.join("bad.toml").display())),
        "{text}"
    );
    // The plan's own error, located in the plan file.
    assert!(
        text.contains(&format!("{}:7:", dir.join("bad.toml").display())),
        "{text}"
    );
    assert!(
        text.contains(&format!(
            "{file}:1:33: plan {}: cannot read",
            dir.join("none.toml").display()
        )),
        "{text}"
    );
    assert!(
        text.contains(&format!("{file}:1:46: plan \"ping\"")) && text.contains("listed twice"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

// verifies: GND-11
#[test]
fn durations_read() {
    assert_eq!(parse_duration_ms("30d"), Some(2_592_000_000));
    assert_eq!(parse_duration_ms("90m"), Some(5_400_000));
    assert_eq!(parse_duration_ms("500ms"), Some(500));
    assert_eq!(parse_duration_ms("0s"), None);
    assert_eq!(parse_duration_ms("d"), None);
    assert_eq!(parse_duration_ms("5x"), None);
}
