//! A valid plan encoded to its TC streams and written out with a listing.

use crate::pus::{self, BuiltTc, SeqCounters};

use super::Plan;

/// One encoded TC of a plan.
#[derive(Clone, Debug)]
pub struct EncodedStep {
    pub step: usize,
    pub tc: Option<BuiltTc>,
}

/// Encodes every step to a TC (per-APID sequence counts from 0, in file order per robot).
pub fn encode(plan: &Plan) -> Result<Vec<EncodedStep>, pus::BuildError> {
    let mut seq = SeqCounters::new();
    plan.steps
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let tc = match s.action.tc() {
                Some((def, args)) => {
                    let apid = mib::apid::robot_apid(s.robot).ok_or(pus::BuildError::UnknownRobot(s.robot))?;
                    Some(pus::build_tc(s.robot, seq.next(apid), def, &args)?)
                }
                None => None,
            };
            Ok(EncodedStep { step: i, tc })
        })
        .collect()
}

/// Writes `apid_0xNNN.bin` per robot (the raw TC stream) and `listing.txt` into `dir`.
/// Returns the paths written.
pub fn write_encoded(
    plan: &Plan,
    enc: &[EncodedStep],
    dir: &std::path::Path,
) -> std::io::Result<Vec<std::path::PathBuf>> {
    use std::fmt::Write as _;
    std::fs::create_dir_all(dir)?;
    let mut streams: std::collections::BTreeMap<u16, Vec<u8>> = std::collections::BTreeMap::new();
    let mut listing = String::new();
    let _ = writeln!(listing, "# plan: {} — {}", plan.name, plan.description);
    let _ = writeln!(listing, "# step | robot | apid | seq | TC | arguments | after | bytes");
    for e in enc {
        let s = &plan.steps[e.step];
        let after: Vec<&str> = s.deps.iter().map(|&d| plan.steps[d].id.as_str()).collect();
        match &e.tc {
            Some(tc) => {
                streams.entry(tc.apid).or_default().extend_from_slice(&tc.bytes);
                let args: Vec<String> = tc
                    .def
                    .args
                    .iter()
                    .zip(&tc.args)
                    .map(|(a, v)| format!("{}={v}", a.name))
                    .collect();
                let _ = writeln!(
                    listing,
                    "{} | {} | 0x{:03X} | {} | TC[{},{}] {} | {} | {} | {}",
                    s.id,
                    s.robot,
                    tc.apid,
                    tc.seq,
                    tc.def.service,
                    tc.def.subservice,
                    tc.def.name,
                    args.join(" "),
                    after.join(","),
                    pus::hex(&tc.bytes)
                );
                let _ = writeln!(listing, "#   {}", s.action.describe());
            }
            None => {
                let _ = writeln!(
                    listing,
                    "{} | {} | - | - | (ground) {} | | {} |",
                    s.id,
                    s.robot,
                    s.action.describe(),
                    after.join(",")
                );
            }
        }
    }
    let mut out = Vec::new();
    for (apid, bytes) in &streams {
        let p = dir.join(format!("apid_0x{apid:03X}.bin"));
        std::fs::write(&p, bytes)?;
        out.push(p);
    }
    let p = dir.join("listing.txt");
    std::fs::write(&p, listing)?;
    out.push(p);
    Ok(out)
}
