//! A valid plan compiled to on-board images: per robot, its steps in file order as the
//! compact checksummed image of `mib::plan` (emitted by `mmic_plan::image`, the code the
//! robot parses it with). Each TC step carries the complete TC the ground would have sent,
//! with a sequence count the ground reserved, so that the robot's PUS 1 reports for it
//! are the ones a ground-driven run gets and the ground tracks them under that request ID.
//! Dependencies on other robots' steps become (robot, step index in that robot's image);
//! a dependency on an earlier step of the same robot is implied by the order.

use mib::plan::{MAX_DEPS, MAX_IMAGE_LEN, MAX_STEPS, MAX_STEP_TC_LEN};
use mmic_plan::image::{crc32, emit, StepRepr};
use mmic_plan::{Dep, StepKind};

use crate::pus::{self, BuiltTc};

use super::{Action, Plan};

/// One robot's image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RobotImage {
    pub robot: u8,
    pub bytes: Vec<u8>,
}

impl RobotImage {
    /// The CRC-32 trailer (PLAN_COMMIT's `crc`).
    pub fn crc(&self) -> u32 {
        let n = self.bytes.len();
        u32::from_be_bytes([
            self.bytes[n - 4],
            self.bytes[n - 3],
            self.bytes[n - 2],
            self.bytes[n - 1],
        ])
    }
}

/// A plan compiled for the robots.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// The same in every image: names this upload of the plan in progress announcements.
    pub plan_id: u32,
    pub images: Vec<RobotImage>,
    /// The TC of each TC step (index into `Plan::steps`).
    pub tcs: Vec<(usize, BuiltTc)>,
}

/// Compiles `plan`; `seq(robot)` reserves the sequence count of the robot's next TC. Every
/// error is returned (step ID and why), nothing is compiled then.
pub fn compile(plan: &Plan, mut seq: impl FnMut(u8) -> Option<u16>) -> Result<Compiled, Vec<String>> {
    let mut errors = Vec::new();
    // Index of each step in its robot's image.
    let mut index = vec![0u8; plan.steps.len()];
    let mut counts: std::collections::BTreeMap<u8, usize> = std::collections::BTreeMap::new();
    for (i, s) in plan.steps.iter().enumerate() {
        let n = counts.entry(s.robot).or_insert(0);
        if *n >= MAX_STEPS {
            errors.push(format!(
                "step \"{}\": robot {} has more than {MAX_STEPS} steps (the MIB's on-board limit)",
                s.id, s.robot
            ));
        }
        index[i] = (*n).min(u8::MAX as usize) as u8;
        *n += 1;
    }
    let mut tcs: Vec<(usize, BuiltTc)> = Vec::new();
    for (i, s) in plan.steps.iter().enumerate() {
        if let Some((def, args)) = s.action.tc() {
            if def.hazard.is_some() && !s.confirm {
                errors.push(format!(
                    "step \"{}\": {} is hazardous: refused without `confirm = true`",
                    s.id, def.name
                ));
            }
            let built = seq(s.robot)
                .ok_or(pus::BuildError::UnknownRobot(s.robot))
                .and_then(|q| pus::build_tc(s.robot, q, def, &args));
            match built {
                Ok(tc) if tc.bytes.len() > MAX_STEP_TC_LEN => errors.push(format!(
                    "step \"{}\": its TC is {} bytes, an on-board step holds at most {MAX_STEP_TC_LEN}",
                    s.id,
                    tc.bytes.len()
                )),
                Ok(tc) => tcs.push((i, tc)),
                Err(e) => errors.push(format!("step \"{}\": {e}", s.id)),
            }
        }
        let cross = s.deps.iter().filter(|&&d| plan.steps[d].robot != s.robot).count();
        if cross > MAX_DEPS {
            errors.push(format!(
                "step \"{}\": {cross} dependencies on other robots, an on-board step holds at most {MAX_DEPS}",
                s.id
            ));
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    // The plan ID: CRC-32 over every step's robot, ID and TC (or wait), so that each
    // upload (new sequence counts) is a new plan for the robots' announcements.
    let mut id_bytes = plan.name.as_bytes().to_vec();
    for (i, s) in plan.steps.iter().enumerate() {
        id_bytes.push(s.robot);
        id_bytes.extend_from_slice(s.id.as_bytes());
        if let Some((_, tc)) = tcs.iter().find(|(k, _)| *k == i) {
            id_bytes.extend_from_slice(&tc.bytes);
        }
    }
    let plan_id = crc32(&id_bytes);
    let mut images = Vec::new();
    for r in &plan.robots {
        let mut steps: Vec<StepRepr> = Vec::new();
        for (i, s) in plan.steps.iter().enumerate().filter(|(_, s)| s.robot == r.number) {
            let deps = s
                .deps
                .iter()
                .filter(|&&d| plan.steps[d].robot != s.robot)
                .map(|&d| Dep {
                    robot: plan.steps[d].robot,
                    step: index[d],
                })
                .collect();
            let kind = match (&s.action, tcs.iter().find(|(k, _)| *k == i)) {
                (_, Some((_, tc))) => StepKind::Tc(&tc.bytes),
                (Action::Wait { seconds }, None) => StepKind::Wait {
                    ms: (seconds * 1000.0).round() as u32,
                },
                (a, None) => {
                    errors.push(format!("step \"{}\": {} has no on-board form", s.id, a.describe()));
                    continue;
                }
            };
            steps.push(StepRepr {
                index: index[i],
                confirmed: s.confirm,
                timeout_s: s
                    .timeout_s
                    .map_or(0, |t| t.ceil().clamp(1.0, f64::from(u16::MAX)) as u16),
                deps,
                kind,
            });
        }
        if steps.is_empty() {
            continue;
        }
        let mut out = vec![0u8; MAX_IMAGE_LEN];
        match emit(r.number, plan_id, &steps, &mut out) {
            Ok(n) => {
                out.truncate(n);
                images.push(RobotImage {
                    robot: r.number,
                    bytes: out,
                });
            }
            Err(e) => errors.push(format!(
                "robot {}: {e} (an on-board image holds at most {MAX_IMAGE_LEN} bytes)",
                r.number
            )),
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    Ok(Compiled { plan_id, images, tcs })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mmic_plan::Image;

    fn demo() -> Plan {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../plans/demo.toml");
        let text = std::fs::read_to_string(path).unwrap();
        super::super::parse(&text).unwrap()
    }

    // verifies: PLAN-IMG-03
    #[test]
    fn the_demo_plan_compiles_to_one_image_per_robot_that_the_robot_parses_back() {
        let plan = demo();
        let mut next = std::collections::HashMap::new();
        let c = compile(&plan, |r| {
            let n = next.entry(r).or_insert(100u16);
            *n += 1;
            Some(*n - 1)
        })
        .unwrap();
        assert_eq!(c.images.len(), 2);
        let r2 = c.images.iter().find(|i| i.robot == 2).unwrap();
        let img = Image::parse(&r2.bytes).unwrap();
        assert_eq!((img.robot, img.plan_id, img.steps()), (2, c.plan_id, 5));
        // r2-walk (robot 2's step 2) waits for r1-bolt (robot 1's step 2).
        let walk = img.step(2).unwrap();
        assert_eq!(walk.deps.as_slice(), &[Dep { robot: 1, step: 2 }]);
        // Each TC in the image is the one the ground tracks, with its reserved count.
        let (_, tc) = c.tcs.iter().find(|(i, _)| plan.steps[*i].id == "r2-walk").unwrap();
        assert_eq!(walk.kind, StepKind::Tc(&tc.bytes));
        assert_eq!(tc.seq, 102);
        // The hazardous steps carry the operator's confirmation.
        assert!(img.step(1).unwrap().confirmed, "r2-unbolt");
        assert!(c.images.iter().all(|i| i.bytes.len() <= MAX_IMAGE_LEN));
    }

    // verifies: PLAN-LOAD-02
    #[test]
    fn an_unconfirmed_hazardous_step_is_refused_before_anything_is_uploaded() {
        let mut plan = demo();
        plan.steps[0].confirm = false;
        let e = compile(&plan, |_| Some(0)).unwrap_err();
        assert!(e[0].contains("r1-operational") && e[0].contains("MODE_SET"), "{e:?}");
    }
}
