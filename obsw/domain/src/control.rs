//! Controllers: open-loop interpolated PWM (arms, grippers) and the hip PI controller.

use crate::consts::{HIP_DONE_TICKS, HIP_MAX_CMD_CDEG_S, HIP_VEL_SPAN};
use mib::robot::servo;

/// Open-loop interpolation of a PWM pulse width toward a target at a fixed rate
/// (`servo::SERVO_SPEED_US_PER_S`, matched to the servos' internal velocity limit).
/// The value fed to the servo each period is [`Interpolator::current`].
#[derive(Clone, Debug)]
pub struct Interpolator {
    current: u16,
    target: u16,
    rate_us_per_s: u16,
    /// Fractional progress carried between ticks (µs·ms).
    acc: u32,
}

impl Interpolator {
    pub fn new(initial: u16, rate_us_per_s: u16) -> Self {
        let v = clamp_pwm(initial);
        Interpolator {
            current: v,
            target: v,
            rate_us_per_s,
            acc: 0,
        }
    }
    /// A servo interpolator at the MIB servo speed.
    pub fn servo(initial: u16) -> Self {
        Self::new(initial, servo::SERVO_SPEED_US_PER_S)
    }
    pub fn set_target(&mut self, target: u16) {
        self.target = clamp_pwm(target);
    }
    /// Stop where the interpolation is now.
    pub fn hold(&mut self) {
        self.target = self.current;
        self.acc = 0;
    }
    /// Jump to a value (used when the true position is known, e.g. at boot).
    pub fn reset_to(&mut self, v: u16) {
        self.current = clamp_pwm(v);
        self.target = self.current;
        self.acc = 0;
    }
    pub fn current(&self) -> u16 {
        self.current
    }
    pub fn target(&self) -> u16 {
        self.target
    }
    pub fn done(&self) -> bool {
        self.current == self.target
    }
    /// Advances by `dt_ms` and returns the new value.
    pub fn tick(&mut self, dt_ms: u32) -> u16 {
        if self.current == self.target {
            self.acc = 0;
            return self.current;
        }
        let budget = self.rate_us_per_s as u32 * dt_ms + self.acc;
        let step = budget / 1000;
        self.acc = budget % 1000;
        let diff = self.target.abs_diff(self.current) as u32;
        if step >= diff {
            self.current = self.target;
            self.acc = 0;
        } else if self.target > self.current {
            self.current += step as u16;
        } else {
            self.current -= step as u16;
        }
        self.current
    }
}

fn clamp_pwm(v: u16) -> u16 {
    v.clamp(servo::PWM_MIN_US, servo::PWM_MAX_US)
}

/// Gains of the hip controller in 1e-3 units (`mib::tunables` HIP_K*).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HipGains {
    pub kp_vel: i32,
    pub ki_vel: i32,
    pub kp_pos: i32,
    pub ki_pos: i32,
}

impl HipGains {
    pub fn from_tunables(t: &crate::tunables::Tunables) -> Self {
        use mib::tunables::tid;
        HipGains {
            kp_vel: t.get(tid::HIP_KP_VEL),
            ki_vel: t.get(tid::HIP_KI_VEL),
            kp_pos: t.get(tid::HIP_KP_POS),
            ki_pos: t.get(tid::HIP_KI_POS),
        }
    }
}

/// Which loop the hip runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HipMode {
    /// |error| > `servo::HIP_SWITCH_CDEG`: track ±`servo::HIP_SPEED_CDEG_S`.
    Velocity,
    /// Within `servo::HIP_SWITCH_CDEG`: PI on the position error.
    Position,
}

/// The hip's PI controller (paper §5): a velocity PI at 10 °/s while the error exceeds
/// 3°, a position PI within 3° whose integrator is frozen inside the done band
/// (`servo::HIP_DONE_CDEG`). The velocity is estimated from the encoder by a
/// difference over `HIP_VEL_SPAN` samples, smoothed. Output: continuous-servo speed
/// command in cdeg/s, clamped to ±`HIP_MAX_CMD_CDEG_S`.
#[derive(Clone, Debug)]
pub struct HipController {
    target: i16,
    gains: HipGains,
    mode: HipMode,
    /// Integral of the velocity error (cdeg) or of the position error (cdeg·ms / 1000).
    integ: i64,
    hist: [i16; HIP_VEL_SPAN],
    hist_len: usize,
    hist_idx: usize,
    vel: i32,
    done_ticks: u8,
    last_cmd: i16,
}

impl HipController {
    pub fn new(target: i16, gains: HipGains) -> Self {
        HipController {
            target,
            gains,
            mode: HipMode::Position,
            integ: 0,
            hist: [0; HIP_VEL_SPAN],
            hist_len: 0,
            hist_idx: 0,
            vel: 0,
            done_ticks: 0,
            last_cmd: 0,
        }
    }
    pub fn set_target(&mut self, target: i16) {
        let t = target.clamp(servo::HIP_MIN_CDEG, servo::HIP_MAX_CDEG);
        if t != self.target {
            self.target = t;
            self.done_ticks = 0;
        }
    }
    pub fn set_gains(&mut self, g: HipGains) {
        self.gains = g;
    }
    pub fn target(&self) -> i16 {
        self.target
    }
    pub fn mode(&self) -> HipMode {
        self.mode
    }
    /// Estimated hip velocity (cdeg/s).
    pub fn velocity(&self) -> i32 {
        self.vel
    }
    pub fn last_command(&self) -> i16 {
        self.last_cmd
    }
    /// Within `servo::HIP_DONE_CDEG` of the target for `HIP_DONE_TICKS` ticks.
    pub fn done(&self) -> bool {
        self.done_ticks >= HIP_DONE_TICKS
    }
    /// Forget the velocity history and integrators (after the hip was unpowered).
    pub fn reset(&mut self) {
        self.integ = 0;
        self.hist_len = 0;
        self.hist_idx = 0;
        self.vel = 0;
        self.done_ticks = 0;
        self.last_cmd = 0;
    }

    fn estimate_velocity(&mut self, angle: i16, dt_ms: u32) {
        if self.hist_len == HIP_VEL_SPAN && dt_ms > 0 {
            let old = self.hist[self.hist_idx] as i32;
            let span_ms = (HIP_VEL_SPAN as u32 * dt_ms) as i32;
            let raw = (angle as i32 - old) * 1000 / span_ms;
            self.vel += (raw - self.vel) / 2;
        }
        self.hist[self.hist_idx] = angle;
        self.hist_idx = (self.hist_idx + 1) % HIP_VEL_SPAN;
        if self.hist_len < HIP_VEL_SPAN {
            self.hist_len += 1;
        }
    }

    /// One control period: measured angle (cdeg) in, speed command (cdeg/s) out.
    pub fn tick(&mut self, angle: i16, dt_ms: u32) -> i16 {
        self.estimate_velocity(angle, dt_ms);
        let err = self.target as i32 - angle as i32;
        let mode = if err.abs() > servo::HIP_SWITCH_CDEG as i32 {
            HipMode::Velocity
        } else {
            HipMode::Position
        };
        if mode != self.mode {
            self.mode = mode;
            self.integ = 0;
        }
        let max = HIP_MAX_CMD_CDEG_S as i64;
        let dt = dt_ms as i64;
        let out = match mode {
            HipMode::Velocity => {
                let v_ref = if err > 0 {
                    servo::HIP_SPEED_CDEG_S as i64
                } else {
                    -(servo::HIP_SPEED_CDEG_S as i64)
                };
                let ev = v_ref - self.vel as i64;
                // integral of the velocity error: cdeg/s * ms
                self.integ += ev * dt;
                let lim = max * 1_000_000 / (self.gains.ki_vel.max(1) as i64);
                self.integ = self.integ.clamp(-lim, lim);
                let i_term = self.gains.ki_vel as i64 * self.integ / 1_000_000;
                v_ref + self.gains.kp_vel as i64 * ev / 1000 + i_term
            }
            HipMode::Position => {
                let e = err as i64;
                // integrate only outside the done band: a hip held against the
                // structure (both grippers closed) must not wind up to a stall current
                if err.abs() > servo::HIP_DONE_CDEG as i32 {
                    self.integ += e * dt; // cdeg·ms
                }
                let lim = max * 1_000_000 / (self.gains.ki_pos.max(1) as i64);
                self.integ = self.integ.clamp(-lim, lim);
                self.gains.kp_pos as i64 * e / 1000 + self.gains.ki_pos as i64 * self.integ / 1_000_000
            }
        };
        if err.abs() <= servo::HIP_DONE_CDEG as i32 {
            self.done_ticks = self.done_ticks.saturating_add(1);
        } else {
            self.done_ticks = 0;
        }
        let cmd = out.clamp(-max, max) as i16;
        self.last_cmd = cmd;
        cmd
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tunables::Tunables;

    // verifies: MMIC-CTL-02
    #[test]
    fn interpolator_moves_at_the_servo_speed() {
        let mut i = Interpolator::servo(1000);
        i.set_target(2000);
        // 500 us/s: 5 us per 10 ms tick, 1000 us in 2 s
        assert_eq!(i.tick(10), 1005);
        for _ in 0..198 {
            i.tick(10);
        }
        assert_eq!(i.current(), 1995);
        assert!(!i.done());
        i.tick(10);
        assert!(i.done());
        assert_eq!(i.current(), 2000);
        // fractional rates accumulate: 3 ms ticks give 1.5 us each
        let mut j = Interpolator::servo(1500);
        j.set_target(1000);
        for _ in 0..10 {
            j.tick(3);
        }
        assert_eq!(j.current(), 1485);
        j.hold();
        j.tick(10);
        assert_eq!(j.current(), 1485);
        // targets are clamped to the commandable range
        j.set_target(5000);
        assert_eq!(j.target(), servo::PWM_MAX_US);
    }

    /// A continuous servo with lag, gain error and a constant load (like the
    /// simulator's), closed around the controller.
    fn run_hip(target: i16, ms: u32, mut record: impl FnMut(u32, f64, HipMode)) -> f64 {
        let mut c = HipController::new(0, HipGains::from_tunables(&Tunables::default()));
        c.set_target(target);
        let (mut angle, mut vel) = (0.0f64, 0.0f64);
        let mut t = 0;
        while t < ms {
            let cmd = c.tick(angle.round() as i16, 10) as f64;
            let v_goal = 0.9 * cmd - 30.0;
            vel += (v_goal - vel) * (10.0 / 80.0);
            angle += vel * 0.01;
            t += 10;
            record(t, angle, c.mode());
        }
        angle
    }

    // verifies: MMIC-CTL-01
    #[test]
    fn hip_pi_reaches_target_at_ten_degrees_per_second_and_switches_at_three_degrees() {
        let mut switched_at = None;
        let mut mid_speed = 0.0;
        let mut last = 0.0;
        let end = run_hip(9000, 15000, |t, a, m| {
            if t == 4000 {
                mid_speed = a - last; // over 10 ms
            }
            last = a;
            if m == HipMode::Position && switched_at.is_none() && t > 100 {
                switched_at = Some(a);
            }
        });
        // velocity mode cruises at ~10 deg/s (1000 cdeg/s = 10 cdeg per 10 ms)
        assert!((mid_speed - 10.0).abs() < 1.5, "cruise {mid_speed} cdeg/tick");
        let sw = switched_at.expect("switched to position mode");
        assert!((9000.0 - sw).abs() <= 320.0, "switched at {sw}");
        assert!((end - 9000.0).abs() <= servo::HIP_DONE_CDEG as f64, "ended at {end}");
    }

    // verifies: MMIC-CTL-01
    #[test]
    fn hip_pi_reports_done_only_when_settled() {
        let mut c = HipController::new(0, HipGains::from_tunables(&Tunables::default()));
        c.set_target(100);
        for _ in 0..HIP_DONE_TICKS {
            c.tick(0, 10);
        }
        assert!(!c.done());
        let mut c2 = HipController::new(100, HipGains::from_tunables(&Tunables::default()));
        for _ in 0..HIP_DONE_TICKS {
            c2.tick(90, 10);
        }
        assert!(c2.done());
        // negative targets work as well
        let end = run_hip(-9000, 15000, |_, _, _| {});
        assert!((end + 9000.0).abs() <= 50.0, "{end}");
    }

    // verifies: MMIC-CTL-03
    #[test]
    fn hip_held_against_the_structure_does_not_wind_up() {
        // blocked hip 40 cdeg off target (inside the done band) for 10 minutes
        let mut c = HipController::new(0, HipGains::from_tunables(&Tunables::default()));
        let mut cmd = 0;
        for _ in 0..60_000 {
            cmd = c.tick(40, 10);
        }
        assert!(c.done());
        assert!(cmd.abs() <= 100, "command grew to {cmd}");
    }
}
