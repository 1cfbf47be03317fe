//! Moving average over a fixed window (paper: every raw sensor channel, 50 samples).

use mib::config::MOVING_AVERAGE_WINDOW;

/// Moving average of the last `N` samples. Until `N` samples have arrived it averages
/// the samples seen so far. Integer arithmetic, rounding to nearest.
#[derive(Clone, Debug)]
pub struct MovingAverage<const N: usize> {
    buf: [i32; N],
    sum: i64,
    idx: usize,
    len: usize,
}

/// The window the paper uses.
pub type Ma = MovingAverage<MOVING_AVERAGE_WINDOW>;

impl<const N: usize> Default for MovingAverage<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> MovingAverage<N> {
    pub const fn new() -> Self {
        MovingAverage {
            buf: [0; N],
            sum: 0,
            idx: 0,
            len: 0,
        }
    }
    /// Adds a sample and returns the new average.
    pub fn push(&mut self, x: i32) -> i32 {
        if N == 0 {
            return x;
        }
        if self.len == N {
            self.sum -= self.buf[self.idx] as i64;
        } else {
            self.len += 1;
        }
        self.buf[self.idx] = x;
        self.sum += x as i64;
        self.idx = (self.idx + 1) % N;
        self.value()
    }
    /// Current average (0 before the first sample).
    pub fn value(&self) -> i32 {
        if self.len == 0 {
            return 0;
        }
        let n = self.len as i64;
        let r = if self.sum >= 0 {
            (self.sum + n / 2) / n
        } else {
            (self.sum - n / 2) / n
        };
        r as i32
    }
    /// Samples in the window (saturates at `N`).
    pub fn len(&self) -> usize {
        self.len
    }
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    pub fn is_full(&self) -> bool {
        self.len == N
    }
    pub fn reset(&mut self) {
        *self = Self::new();
    }
}

/// Saturating conversion of an average to `u16`.
pub fn to_u16(v: i32) -> u16 {
    v.clamp(0, u16::MAX as i32) as u16
}

/// Saturating conversion of an average to `i16`.
pub fn to_i16(v: i32) -> i16 {
    v.clamp(i16::MIN as i32, i16::MAX as i32) as i16
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: MMIC-AV-02
    #[test]
    fn moving_average_uses_a_window_of_fifty_samples() {
        let mut m = Ma::new();
        for _ in 0..50 {
            m.push(0);
        }
        // a step of 1000: after k samples the average is 1000*k/50
        for k in 1..=50 {
            let v = m.push(1000);
            assert_eq!(v, 1000 * k / 50, "after {k} samples");
        }
        assert!(m.is_full());
        assert_eq!(m.push(1000), 1000);
    }
    // verifies: MMIC-AV-02
    #[test]
    fn moving_average_partial_window_and_negatives() {
        let mut m = MovingAverage::<4>::new();
        assert_eq!(m.value(), 0);
        assert_eq!(m.push(-3), -3);
        assert_eq!(m.push(-4), -4); // -3.5 rounds away from zero
        m.push(10);
        m.push(10);
        assert_eq!(m.push(10), 7); // window -4, 10, 10, 10: 26/4 = 6.5 rounds to 7
    }
}
