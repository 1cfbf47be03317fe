//! Column chunks of one parameter: `(time, raw value)` samples packed as zig-zag varints.
//!
//! Layout of a chunk BLOB: `varint n`, then the time column, then the value column.
//! Times are stored as the first time and then delta-of-delta (a steady HK period costs
//! nothing); values as the first value and then deltas. In both columns a token is
//! `zigzag(d) << 1` for one value `d` and `(k << 1) | 1` for `k` zeros in a row, so a
//! constant parameter costs a few bytes per chunk.

use std::fmt;

/// A chunk BLOB that does not decode (a damaged archive, never our own output).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChunkError {
    pub at: usize,
}

impl fmt::Display for ChunkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "damaged parameter chunk (byte {})", self.at)
    }
}

fn put_varint(out: &mut Vec<u8>, mut v: u128) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

fn get_varint(b: &[u8], pos: &mut usize) -> Result<u128, ChunkError> {
    let mut v: u128 = 0;
    let mut shift = 0;
    loop {
        let byte = *b.get(*pos).ok_or(ChunkError { at: *pos })?;
        *pos += 1;
        if shift > 126 {
            return Err(ChunkError { at: *pos });
        }
        v |= ((byte & 0x7F) as u128) << shift;
        if byte & 0x80 == 0 {
            return Ok(v);
        }
        shift += 7;
    }
}

fn zigzag(d: i128) -> u128 {
    ((d << 1) ^ (d >> 127)) as u128
}

fn unzigzag(u: u128) -> i128 {
    ((u >> 1) as i128) ^ -((u & 1) as i128)
}

/// One column of differences being written: its tokens so far and the zero run not yet
/// written (a run is only known to end when the next non-zero difference comes).
#[derive(Clone, Debug, Default)]
struct Column {
    bytes: Vec<u8>,
    zeros: u128,
}

impl Column {
    fn push(&mut self, d: i128) {
        if d == 0 {
            self.zeros += 1;
            return;
        }
        if self.zeros > 0 {
            put_varint(&mut self.bytes, (self.zeros << 1) | 1);
            self.zeros = 0;
        }
        put_varint(&mut self.bytes, zigzag(d) << 1);
    }

    fn write_to(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.bytes);
        if self.zeros > 0 {
            put_varint(out, (self.zeros << 1) | 1);
        }
    }
}

/// A chunk built one sample at a time: appending costs the new sample's tokens only, and
/// [`ChunkEncoder::bytes`] is the chunk BLOB of the samples so far. An open
/// chunk is rewritten many times while it fills; re-encoding all of it each time made
/// the writer's work grow with the chunk.
#[derive(Clone, Debug, Default)]
pub(crate) struct ChunkEncoder {
    n: usize,
    first_t: i64,
    prev_t: i64,
    prev_dt: i128,
    first_v: i64,
    prev_v: i64,
    times: Column,
    values: Column,
}

impl ChunkEncoder {
    pub fn push(&mut self, t: i64, v: i64) {
        if self.n == 0 {
            self.first_t = t;
            self.first_v = v;
        } else {
            let dt = t as i128 - self.prev_t as i128;
            self.times.push(dt - self.prev_dt);
            self.prev_dt = dt;
            self.values.push(v as i128 - self.prev_v as i128);
        }
        self.prev_t = t;
        self.prev_v = v;
        self.n += 1;
    }

    /// Samples so far.
    pub fn len(&self) -> usize {
        self.n
    }

    /// The chunk BLOB of the samples so far.
    pub fn bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(24 + self.times.bytes.len() + self.values.bytes.len());
        put_varint(&mut out, self.n as u128);
        if self.n == 0 {
            return out;
        }
        put_varint(&mut out, zigzag(self.first_t as i128));
        self.times.write_to(&mut out);
        put_varint(&mut out, zigzag(self.first_v as i128));
        self.values.write_to(&mut out);
        out
    }
}

/// Reads `n` differences into `each`.
fn get_column(b: &[u8], pos: &mut usize, n: usize, mut each: impl FnMut(i128)) -> Result<(), ChunkError> {
    let mut got = 0;
    while got < n {
        let tok = get_varint(b, pos)?;
        if tok & 1 == 1 {
            let k = (tok >> 1) as usize;
            if k == 0 || got + k > n {
                return Err(ChunkError { at: *pos });
            }
            for _ in 0..k {
                each(0);
            }
            got += k;
        } else {
            each(unzigzag(tok >> 1));
            got += 1;
        }
    }
    Ok(())
}

/// Unpacks a chunk into `(times, values)`.
pub fn decode(b: &[u8]) -> Result<(Vec<i64>, Vec<i64>), ChunkError> {
    let mut pos = 0;
    let n = get_varint(b, &mut pos)? as usize;
    // Runs make `n` independent of the length: reserve at most one chunk's worth.
    let reserve = n.min(super::schema::CHUNK_MAX);
    let mut times = Vec::with_capacity(reserve);
    let mut values = Vec::with_capacity(reserve);
    if n == 0 {
        return Ok((times, values));
    }
    let mut t = unzigzag(get_varint(b, &mut pos)?);
    times.push(t as i64);
    let mut dt: i128 = 0;
    get_column(b, &mut pos, n - 1, |dod| {
        dt += dod;
        t += dt;
        times.push(t as i64);
    })?;
    let mut v = unzigzag(get_varint(b, &mut pos)?);
    values.push(v as i64);
    get_column(b, &mut pos, n - 1, |d| {
        v += d;
        values.push(v as i64);
    })?;
    if pos != b.len() {
        return Err(ChunkError { at: pos });
    }
    Ok((times, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Packs samples (in the order given; times need not be sorted).
    fn encode(times: &[i64], values: &[i64]) -> Vec<u8> {
        let mut enc = ChunkEncoder::default();
        for (t, v) in times.iter().zip(values) {
            enc.push(*t, *v);
        }
        enc.bytes()
    }

    // verifies: GND-02
    #[test]
    fn round_trip_steady_noisy_and_extreme() {
        let cases: Vec<(Vec<i64>, Vec<i64>)> = vec![
            (vec![], vec![]),
            (vec![5], vec![-7]),
            ((0..1000).map(|i| 1_767_225_600_000 + i * 100).collect(), vec![42; 1000]),
            (
                (0..500).map(|i| 1_000 + i * 100 + (i % 3)).collect(),
                (0..500).map(|i| (i * 7919) % 4096 - 2048).collect(),
            ),
            (vec![i64::MAX, i64::MIN, 0, i64::MAX], vec![i64::MIN, i64::MAX, -1, 1]),
            (vec![300, 200, 100, 100], vec![1, 1, 0, 0]),
        ];
        for (t, v) in cases {
            let b = encode(&t, &v);
            assert_eq!(decode(&b).unwrap(), (t, v));
        }
    }

    // verifies: GND-02
    #[test]
    fn steady_period_and_constant_value_cost_almost_nothing() {
        let t: Vec<i64> = (0..1024).map(|i| 1_767_225_600_000 + i * 100).collect();
        let b = encode(&t, &vec![3; 1024]);
        assert!(b.len() < 20, "{} bytes", b.len());
    }

    // verifies: GND-02
    #[test]
    fn every_prefix_of_an_appended_chunk_decodes_to_its_samples() {
        // Zero runs that end, that are still open, and value runs across the two columns.
        let t: Vec<i64> = (0..300)
            .map(|i| 1_000 + i * 100 + if i % 50 == 7 { 3 } else { 0 })
            .collect();
        let v: Vec<i64> = (0..300).map(|i| if i % 40 < 30 { 5 } else { i }).collect();
        let mut enc = ChunkEncoder::default();
        for k in 0..t.len() {
            enc.push(t[k], v[k]);
            assert_eq!(enc.len(), k + 1);
            let b = enc.bytes();
            assert_eq!(
                decode(&b).unwrap(),
                (t[..=k].to_vec(), v[..=k].to_vec()),
                "after {} samples",
                k + 1
            );
        }
        // The open zero runs were merged, not written one token per sample.
        assert!(enc.bytes().len() < 300, "{} bytes", enc.bytes().len());
        assert_eq!(decode(&ChunkEncoder::default().bytes()).unwrap(), (vec![], vec![]));
    }

    // verifies: GND-08
    #[test]
    fn damaged_chunks_are_errors_not_panics() {
        let b = encode(&[1, 2, 3], &[4, 5, 6]);
        for cut in 0..b.len() {
            assert!(decode(&b[..cut]).is_err());
        }
        assert!(decode(&[0xFF; 40]).is_err());
        let mut long = b.clone();
        long.push(0);
        assert!(decode(&long).is_err());
    }
}
