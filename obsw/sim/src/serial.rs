//! A simulated serial line (115200 Bd, 8N1): bytes are delivered in order after their
//! transmission time; each byte may be lost or have a bit flipped with configured
//! probabilities; a cut cable delivers nothing.

use rand::Rng;
use std::collections::VecDeque;

/// Microseconds on the wire per byte (10 bits per byte at the MIB baud rate).
pub fn byte_time_us() -> u64 {
    (10_000_000 / mib::config::AB_LINK_BAUD as u64).max(1)
}

/// Line statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineStats {
    pub sent: u64,
    pub lost: u64,
    pub corrupted: u64,
    pub delivered: u64,
}

/// One direction of the cable.
#[derive(Clone, Debug, Default)]
pub struct SerialLine {
    q: VecDeque<(u64, u8)>,
    busy_until_us: u64,
    pub stats: LineStats,
}

impl SerialLine {
    /// Queues bytes written at `t_us`.
    pub fn send<R: Rng>(&mut self, t_us: u64, bytes: &[u8], loss: f64, corrupt: f64, cut: bool, rng: &mut R) {
        let bt = byte_time_us();
        let mut t = self.busy_until_us.max(t_us);
        for &b in bytes {
            t += bt;
            self.stats.sent += 1;
            if cut {
                self.stats.lost += 1;
                continue;
            }
            if loss > 0.0 && rng.gen_bool(loss.clamp(0.0, 1.0)) {
                self.stats.lost += 1;
                continue;
            }
            let mut v = b;
            if corrupt > 0.0 && rng.gen_bool(corrupt.clamp(0.0, 1.0)) {
                v ^= 1 << rng.gen_range(0..8);
                self.stats.corrupted += 1;
            }
            self.q.push_back((t, v));
        }
        self.busy_until_us = t;
    }
    /// Moves every byte that has arrived by `t_us` into `out`.
    pub fn recv(&mut self, t_us: u64, out: &mut Vec<u8>) {
        while let Some(&(t, b)) = self.q.front() {
            if t > t_us {
                break;
            }
            out.push(b);
            self.q.pop_front();
            self.stats.delivered += 1;
        }
    }
    /// Drops everything in transit (the cable was cut).
    pub fn drop_in_transit(&mut self) {
        self.stats.lost += self.q.len() as u64;
        self.q.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    // verifies: MMIC-AB-07
    #[test]
    fn serial_line_delivers_in_order_after_transmission_time() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let mut l = SerialLine::default();
        l.send(0, &[1, 2, 3], 0.0, 0.0, false, &mut rng);
        let mut out = Vec::new();
        l.recv(byte_time_us() * 2, &mut out);
        assert_eq!(out, [1, 2]);
        l.recv(1_000_000, &mut out);
        assert_eq!(out, [1, 2, 3]);
        l.send(0, &[9; 100], 0.0, 0.0, true, &mut rng);
        l.recv(10_000_000, &mut out);
        assert_eq!(out.len(), 3, "a cut cable delivers nothing");
    }

    // verifies: MMIC-AB-07
    #[test]
    fn serial_line_loss_and_corruption_rates() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let mut l = SerialLine::default();
        let data = vec![0x55u8; 20_000];
        l.send(0, &data, 0.1, 0.05, false, &mut rng);
        let mut out = Vec::new();
        l.recv(u64::MAX, &mut out);
        let lost = 20_000 - out.len();
        assert!((1700..2300).contains(&lost), "lost {lost}");
        let bad = out.iter().filter(|&&b| b != 0x55).count();
        assert!((700..1100).contains(&bad), "corrupted {bad}");
    }
}
