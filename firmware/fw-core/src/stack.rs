//! The stack's high-water mark of an image: the stack is painted with
//! [`mib::memory::STACK_PAINT`] at start-up; [`StackWatch::step`] then looks at a bounded
//! number of words per control period, from the stack's bottom up, and the lowest word no
//! longer holding the paint is the deepest the stack has reached. No `unsafe` here: the
//! image reads the words (`fw_esp::stack`).

/// A painted 32-bit word.
pub const PAINT_WORD: u32 = u32::from_ne_bytes([mib::memory::STACK_PAINT; 4]);

/// Words [`StackWatch::step`] looks at per control period: about 5 000 instructions, and
/// a full sweep of board A's ≈ 225 KiB stack in about half a second.
pub const WORDS_PER_PERIOD: usize = 1024;

/// Sweeps the painted stack `bottom..top` (addresses, `bottom` the lowest painted word,
/// `top` one past the stack's highest byte).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StackWatch {
    bottom: usize,
    top: usize,
    /// Lowest address found written (`top` before the first find).
    low: usize,
    cursor: usize,
}

impl StackWatch {
    pub const fn new(bottom: usize, top: usize) -> Self {
        StackWatch {
            bottom,
            top,
            low: top,
            cursor: bottom,
        }
    }

    /// Looks at up to `words` words from where the last call stopped (`read` gives the
    /// word at an address); returns the high-water mark in bytes below `top`. A sweep
    /// restarts at the bottom when it reaches the lowest written word found so far, so a
    /// deeper use later is found within one sweep.
    pub fn step(&mut self, words: usize, mut read: impl FnMut(usize) -> u32) -> u32 {
        for _ in 0..words {
            if self.cursor >= self.low {
                self.cursor = self.bottom;
                break;
            }
            if read(self.cursor) != PAINT_WORD {
                self.low = self.cursor;
                self.cursor = self.bottom;
                break;
            }
            self.cursor += 4;
        }
        self.high_water()
    }

    /// Deepest use found so far, in bytes.
    pub fn high_water(&self) -> u32 {
        (self.top - self.low) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4 KiB stack at address 0x1000 as words, painted, the top `used` bytes written.
    fn stack(used: usize) -> [u32; 1024] {
        let mut m = [PAINT_WORD; 1024];
        for w in m.iter_mut().rev().take(used / 4) {
            *w = 0x1234_5678;
        }
        m
    }

    fn sweep(w: &mut StackWatch, m: &[u32; 1024], periods: usize) -> u32 {
        let mut hw = 0;
        for _ in 0..periods {
            hw = w.step(64, |a| m[(a - 0x1000) / 4]);
        }
        hw
    }

    // verifies: FW-MEM-02
    #[test]
    fn stack_watch_finds_the_deepest_use_and_a_deeper_one_later() {
        let mut w = StackWatch::new(0x1000, 0x2000);
        let m = stack(600);
        assert_eq!(w.step(1, |_| PAINT_WORD), 0, "nothing found yet");
        // 1024 words at 64 per period: found within one sweep (16 periods).
        assert_eq!(sweep(&mut w, &m, 17), 600);
        // Deeper use later (a word left as painted inside it does not hide it).
        let mut m = stack(2000);
        m[1024 - 300] = PAINT_WORD;
        assert_eq!(sweep(&mut w, &m, 17), 2000);
        // Shallower use afterwards: the mark stays.
        assert_eq!(sweep(&mut w, &stack(100), 17), 2000);
    }

    // verifies: FW-MEM-02
    #[test]
    fn stack_watch_reports_a_full_stack() {
        let mut w = StackWatch::new(0x1000, 0x2000);
        assert_eq!(sweep(&mut w, &stack(4096), 2), 4096);
    }
}
