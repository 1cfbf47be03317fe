//! Moving average over a fixed window (paper: every raw reading, window of 50).

/// Integer moving average of the last `N` samples. Before `N` samples arrived it
/// averages what it has.
#[derive(Clone, Debug)]
pub struct MovingAverage<const N: usize> {
    buf: [u16; N],
    next: usize,
    len: usize,
    sum: u32,
}

impl<const N: usize> Default for MovingAverage<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> MovingAverage<N> {
    const NONEMPTY: () = assert!(N > 0 && N <= 65_536);

    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::NONEMPTY;
        Self {
            buf: [0; N],
            next: 0,
            len: 0,
            sum: 0,
        }
    }

    /// Adds a sample and returns the new average (rounded to nearest).
    pub fn push(&mut self, sample: u16) -> u16 {
        if self.len == N {
            self.sum -= u32::from(self.buf[self.next]);
        } else {
            self.len += 1;
        }
        self.buf[self.next] = sample;
        self.sum += u32::from(sample);
        self.next = (self.next + 1) % N;
        self.value()
    }

    /// Current average (0 before the first sample).
    pub fn value(&self) -> u16 {
        if self.len == 0 {
            return 0;
        }
        let len = self.len as u32;
        ((self.sum + len / 2) / len) as u16
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}
