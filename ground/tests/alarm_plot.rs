//! `ground archive plot` tells the truth: parameters of different
//! units get panels of their own, each with its own y axis labelled with its unit (volts
//! and amperes on one axis labelled "V, A" flattened the voltage), and a hole in the data
//! is drawn as a gap, not as a straight ramp across it. Checked on the SVG the real
//! binary writes from an archive of known HK (and on a PNG's size).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ground::pus::{build_tm, CdsShort};
use mib::params::{by_id, pid};

const T0: i64 = 1_767_225_600_000;

/// ROBOT_STATUS of robot 1 at `t_ms` with V_BAT_A = `v` volts, I_BAT = `i` amperes.
fn hk(seq: u16, t_ms: i64, v: f64, i: f64) -> Vec<u8> {
    let def = mib::hk::by_sid(mib::hk::sid::ROBOT_STATUS).unwrap();
    let raw = |id: u16, eng: f64| by_id(id).unwrap().calib.raw(eng);
    let mut src = [0u8; 512];
    let n = mib_wire::codec::encode_hk(
        def,
        |id| match id {
            pid::V_BAT_A => raw(id, v),
            pid::I_BAT => raw(id, i),
            _ => 0,
        },
        &mut src,
    )
    .unwrap();
    let apid = mib::apid::robot_apid(1).unwrap();
    build_tm(apid, seq, 3, 25, 0, &CdsShort::from_unix_ms(t_ms).to_bytes(), &src[..n])
}

/// An archive with 1 Hz HK for 100 s, a 200 s hole, then 100 s more: V_BAT_A a
/// triangle between 11.0 and 12.6 V, I_BAT one between 0.2 and 1.0 A.
fn archive(dir: &Path) -> PathBuf {
    let mut buf = Vec::new();
    for (seq, s) in (0..100i64).chain(300..400).enumerate() {
        let phase = (s % 20) as f64 / 20.0;
        let tri = if phase < 0.5 { phase * 2.0 } else { 2.0 - phase * 2.0 };
        buf.extend(hk(seq as u16, T0 + s * 1000, 11.0 + 1.6 * tri, 0.2 + 0.8 * tri));
    }
    let file = dir.join("hk.bin");
    std::fs::write(&file, buf).unwrap();
    let db = dir.join("a.db");
    let out = ground(
        dir,
        &["--archive", "a.db", "archive", "import", "hk.bin", "--robot", "1"],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    db
}

fn ground(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ground"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ground-alarm-plot-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The values of attribute `attr` of every `<tag` element of an SVG (plotters writes
/// flat SVG: no nesting that matters here).
fn attrs<'a>(svg: &'a str, tag: &str, attr: &str) -> Vec<&'a str> {
    let open = format!("<{tag} ");
    let key = format!(" {attr}=\"");
    svg.match_indices(&open)
        .filter_map(|(i, _)| {
            let el = &svg[i..i + svg[i..].find('>')?];
            let start = el.find(&key)? + key.len();
            Some(&el[start..start + el[start..].find('"')?])
        })
        .collect()
}

/// The data lines of an SVG: `<polyline>`s of more than two points (a legend sample
/// has two), as lists of (x, y) pixels.
fn lines(svg: &str) -> Vec<Vec<(f64, f64)>> {
    attrs(svg, "polyline", "points")
        .into_iter()
        .map(|pts| {
            pts.split_whitespace()
                .filter_map(|p| {
                    let (x, y) = p.split_once(',')?;
                    Some((x.parse().ok()?, y.parse().ok()?))
                })
                .collect::<Vec<_>>()
        })
        .filter(|pts| pts.len() > 2)
        .collect()
}

/// The texts of an SVG.
fn texts(svg: &str) -> Vec<String> {
    svg.match_indices("<text")
        .filter_map(|(i, _)| {
            let rest = &svg[i..];
            let body = &rest[rest.find('>')? + 1..rest.find("</text>")?];
            Some(body.trim().to_string())
        })
        .collect()
}

/// The height of an SVG (pixels).
fn height(svg: &str) -> f64 {
    attrs(svg, "svg", "height")[0].parse().unwrap()
}

fn plot(dir: &Path, args: &[&str]) -> String {
    let mut a = vec!["--archive", "a.db", "archive", "plot"];
    a.extend(args);
    a.extend(["--out", "p.svg"]);
    let out = ground(dir, &a);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::read_to_string(dir.join("p.svg")).unwrap()
}

// verifies: ALM-PLOT-01
#[test]
fn volts_and_amperes_get_a_panel_and_an_axis_each() {
    let dir = tmpdir("units");
    archive(&dir);
    let svg = plot(&dir, &["V_BAT_A", "I_BAT"]);
    let t = texts(&svg);
    assert!(!t.iter().any(|s| s.contains("V, A")), "one axis for two units: {t:?}");
    assert!(
        t.iter().any(|s| s == "V") && t.iter().any(|s| s == "A"),
        "axis labels: {t:?}"
    );
    let l = lines(&svg);
    assert!(!l.is_empty(), "no data lines in the plot");
    // Each line fills most of its own panel's height (320 px): on one shared axis
    // (0.2 .. 12.6) the current would take 6 % of it and the voltage 13 %.
    for pts in &l {
        let (lo, hi) = pts
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
        assert!(
            hi - lo > 150.0,
            "a line spans only {:.0} px of height: {pts:?}",
            hi - lo
        );
    }
    // The two panels are stacked: the lines of the second lie below those of the first.
    let top = |pts: &Vec<(f64, f64)>| pts.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    let mut tops: Vec<f64> = l.iter().map(top).collect();
    tops.sort_by(f64::total_cmp);
    assert!(
        tops.last().unwrap() - tops.first().unwrap() > 250.0,
        "one panel only: {tops:?}"
    );
    // The same parameters in one unit share one panel.
    let h = height(&plot(&dir, &["V_BAT_A", "V_BAT_B"]));
    let h2 = height(&svg);
    assert!(h2 > h, "two units, two panels: {h} vs {h2} px");
}

// verifies: ALM-PLOT-02
#[test]
fn a_hole_in_the_data_is_drawn_as_a_gap() {
    let dir = tmpdir("gap");
    archive(&dir);
    let svg = plot(&dir, &["V_BAT_A"]);
    let l = lines(&svg);
    // 100 s, a 200 s hole, 100 s: two runs, neither stepping across the hole (which is
    // half the width of the time axis).
    assert_eq!(
        l.len(),
        2,
        "the line should break at the hole into 2 runs, not {}",
        l.len()
    );
    for pts in &l {
        let widest = pts.windows(2).map(|w| (w[1].0 - w[0].0).abs()).fold(0.0, f64::max);
        assert!(widest < 50.0, "a step of {widest:.0} px across the hole");
    }
    // PNG: the same panels (height grows with the number of units).
    let out = ground(
        &dir,
        &[
            "--archive",
            "a.db",
            "archive",
            "plot",
            "V_BAT_A",
            "I_BAT",
            "--out",
            "p.png",
        ],
    );
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let png = std::fs::read(dir.join("p.png")).unwrap();
    assert_eq!(&png[..4], b"\x89PNG");
    let height = u32::from_be_bytes([png[20], png[21], png[22], png[23]]);
    assert!(height > 560, "two panels in the PNG: {height} px high");
}
