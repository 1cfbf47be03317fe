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

/// Writes a column of differences with zero runs.
fn put_column(out: &mut Vec<u8>, diffs: impl Iterator<Item = i128>) {
    let mut zeros: u128 = 0;
    for d in diffs {
        if d == 0 {
            zeros += 1;
            continue;
        }
        if zeros > 0 {
            put_varint(out, (zeros << 1) | 1);
            zeros = 0;
        }
        put_varint(out, zigzag(d) << 1);
    }
    if zeros > 0 {
        put_varint(out, (zeros << 1) | 1);
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

/// Packs samples (in the order given; times need not be sorted).
pub fn encode(times: &[i64], values: &[i64]) -> Vec<u8> {
    let n = times.len().min(values.len());
    let mut out = Vec::with_capacity(8 + n * 2);
    put_varint(&mut out, n as u128);
    if n == 0 {
        return out;
    }
    put_varint(&mut out, zigzag(times[0] as i128));
    let mut prev_dt: i128 = 0;
    put_column(
        &mut out,
        times[..n].windows(2).map(|w| {
            let dt = w[1] as i128 - w[0] as i128;
            let dod = dt - prev_dt;
            prev_dt = dt;
            dod
        }),
    );
    put_varint(&mut out, zigzag(values[0] as i128));
    put_column(&mut out, values[..n].windows(2).map(|w| w[1] as i128 - w[0] as i128));
    out
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
