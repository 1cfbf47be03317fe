//! The plan image: parse (checked, for uplinked bytes) and emit (the ground's compiler).
//! The layout and every limit are in `mib::plan`.

use mib::plan::{
    flag, invalid, CRC_LEN, HEADER_LEN, MAGIC, MAX_DEPS, MAX_STEPS, MAX_STEP_TC_LEN, MAX_WAIT_MS, VERSION,
};

const CRC32: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 (ISO-HDLC) as the image's trailer and PLAN_COMMIT carry it.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// A step waits for robot `robot`'s step `step` (0-based in that robot's image).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Dep {
    pub robot: u8,
    pub step: u8,
}

/// What a step does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepKind<'a> {
    /// Run this TC (a complete space packet with its CRC).
    Tc(&'a [u8]),
    /// Wait this long.
    Wait { ms: u32 },
}

/// One step of an image, as parsed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StepView<'a> {
    pub index: u8,
    /// The operator confirmed the step's hazardous TC.
    pub confirmed: bool,
    /// Timeout in seconds (0: `mib::plan::DEFAULT_STEP_TIMEOUT_S`).
    pub timeout_s: u16,
    pub deps: heapless::Vec<Dep, MAX_DEPS>,
    pub kind: StepKind<'a>,
}

/// A step to emit.
pub type StepRepr<'a> = StepView<'a>;

/// Why bytes are not a plan image: a `mib::plan::invalid` reason and where.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageError {
    /// The trailer's CRC-32 is not the bytes' (`expected` from the trailer).
    Checksum { expected: u32, computed: u32 },
    /// A `mib::plan::invalid` reason at byte `offset`.
    Invalid { reason: u8, offset: u16 },
}

impl core::fmt::Display for ImageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ImageError::Checksum { expected, computed } => {
                write!(
                    f,
                    "CRC-32 {computed:#010x} of the image is not its trailer's {expected:#010x}"
                )
            }
            ImageError::Invalid { reason, offset } => write!(f, "invalid image (reason {reason}) at byte {offset}"),
        }
    }
}

impl core::error::Error for ImageError {}

fn bad(reason: u8, offset: usize) -> ImageError {
    ImageError::Invalid {
        reason,
        offset: offset.min(u16::MAX as usize) as u16,
    }
}

/// A checked image: header fields and the offsets of its steps.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image<'a> {
    bytes: &'a [u8],
    pub robot: u8,
    pub plan_id: u32,
    offsets: heapless::Vec<u16, MAX_STEPS>,
}

/// A cursor over the image's bytes that reports where it ran short.
struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], ImageError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        match end {
            Some(e) => {
                let s = &self.b[self.at..e];
                self.at = e;
                Ok(s)
            }
            None => Err(bad(invalid::LENGTH, self.at)),
        }
    }
    fn u8(&mut self) -> Result<u8, ImageError> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16, ImageError> {
        let s = self.take(2)?;
        Ok(u16::from_be_bytes([s[0], s[1]]))
    }
    fn u32(&mut self) -> Result<u32, ImageError> {
        let s = self.take(4)?;
        Ok(u32::from_be_bytes([s[0], s[1], s[2], s[3]]))
    }
}

/// Reads the step at the cursor (index `index`), checking its fields.
fn read_step<'a>(c: &mut Cursor<'a>, index: u8) -> Result<StepView<'a>, ImageError> {
    let start = c.at;
    let flags = c.u8()?;
    if flags & !flag::ALL != 0 {
        return Err(bad(invalid::STEP, start));
    }
    let timeout_s = c.u16()?;
    let n = c.u8()?;
    if usize::from(n) > MAX_DEPS {
        return Err(bad(invalid::LIMITS, c.at - 1));
    }
    let mut deps = heapless::Vec::new();
    for _ in 0..n {
        let at = c.at;
        let d = Dep {
            robot: c.u8()?,
            step: c.u8()?,
        };
        if d.robot == 0 || usize::from(d.step) >= MAX_STEPS {
            return Err(bad(invalid::DEPENDENCY, at));
        }
        // Capacity checked above.
        let _ = deps.push(d);
    }
    let kind = if flags & flag::WAIT != 0 {
        let at = c.at;
        let ms = c.u32()?;
        if ms > MAX_WAIT_MS {
            return Err(bad(invalid::STEP, at));
        }
        StepKind::Wait { ms }
    } else {
        let at = c.at;
        let len = usize::from(c.u8()?);
        if len == 0 || len > MAX_STEP_TC_LEN {
            return Err(bad(invalid::STEP, at));
        }
        StepKind::Tc(c.take(len)?)
    };
    Ok(StepView {
        index,
        confirmed: flags & flag::CONFIRMED != 0,
        timeout_s,
        deps,
        kind,
    })
}

impl<'a> Image<'a> {
    /// Checks uplinked bytes: CRC-32 trailer first (a corrupted image is refused as such,
    /// whatever else it breaks), then the format and the limits of `mib::plan`, and that
    /// a dependency on this image's own robot names an earlier step.
    pub fn parse(bytes: &'a [u8]) -> Result<Image<'a>, ImageError> {
        if bytes.len() < HEADER_LEN + CRC_LEN {
            return Err(bad(invalid::LENGTH, bytes.len()));
        }
        let (body, trailer) = bytes.split_at(bytes.len() - CRC_LEN);
        let expected = u32::from_be_bytes([trailer[0], trailer[1], trailer[2], trailer[3]]);
        let computed = crc32(body);
        if expected != computed {
            return Err(ImageError::Checksum { expected, computed });
        }
        let mut c = Cursor { b: body, at: 0 };
        if c.take(2)? != MAGIC || c.u8()? != VERSION {
            return Err(bad(invalid::FORMAT, 0));
        }
        let robot = c.u8()?;
        let plan_id = c.u32()?;
        let steps = c.u8()?;
        if steps == 0 || usize::from(steps) > MAX_STEPS {
            return Err(bad(invalid::LIMITS, HEADER_LEN - 1));
        }
        let mut offsets = heapless::Vec::new();
        for i in 0..steps {
            let at = c.at;
            let s = read_step(&mut c, i)?;
            if s.deps.iter().any(|d| d.robot == robot && d.step >= i) {
                return Err(bad(invalid::DEPENDENCY, at));
            }
            // `steps` <= MAX_STEPS was checked.
            let _ = offsets.push(at as u16);
        }
        if c.at != body.len() {
            return Err(bad(invalid::LENGTH, c.at));
        }
        Ok(Image {
            bytes: body,
            robot,
            plan_id,
            offsets,
        })
    }

    pub fn steps(&self) -> u8 {
        self.offsets.len() as u8
    }

    /// Step `i` (`None` beyond the last).
    pub fn step(&self, i: u8) -> Option<StepView<'a>> {
        let at = usize::from(*self.offsets.get(usize::from(i))?);
        let mut c = Cursor { b: self.bytes, at };
        read_step(&mut c, i).ok()
    }

    /// Every step in order.
    pub fn iter(&self) -> impl Iterator<Item = StepView<'a>> + '_ {
        (0..self.steps()).filter_map(|i| self.step(i))
    }
}

/// Why an image could not be emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitError {
    /// The output buffer is too small.
    BufferTooSmall,
    /// No step, or more than `MAX_STEPS`.
    StepCount(usize),
    /// A step's TC is empty or longer than `MAX_STEP_TC_LEN`, or a wait too long.
    Step(usize),
}

impl core::fmt::Display for EmitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            EmitError::BufferTooSmall => f.write_str("the image does not fit the buffer"),
            EmitError::StepCount(n) => write!(f, "{n} steps: an image holds 1..={MAX_STEPS}"),
            EmitError::Step(i) => write!(
                f,
                "step {i}: a TC of 1..={MAX_STEP_TC_LEN} bytes or a wait of at most {MAX_WAIT_MS} ms"
            ),
        }
    }
}

impl core::error::Error for EmitError {}

/// Writes the image of `steps` for robot `robot` of plan `plan_id` into `out`; returns
/// its length (CRC-32 trailer included).
pub fn emit(robot: u8, plan_id: u32, steps: &[StepRepr<'_>], out: &mut [u8]) -> Result<usize, EmitError> {
    if steps.is_empty() || steps.len() > MAX_STEPS {
        return Err(EmitError::StepCount(steps.len()));
    }
    let mut w = Writer { out, at: 0 };
    w.put(&MAGIC)?;
    w.put(&[VERSION, robot])?;
    w.put(&plan_id.to_be_bytes())?;
    w.put(&[steps.len() as u8])?;
    for (i, s) in steps.iter().enumerate() {
        let flags = match s.kind {
            StepKind::Wait { .. } => flag::WAIT,
            StepKind::Tc(_) => 0,
        } | if s.confirmed { flag::CONFIRMED } else { 0 };
        w.put(&[flags])?;
        w.put(&s.timeout_s.to_be_bytes())?;
        w.put(&[s.deps.len() as u8])?;
        for d in &s.deps {
            w.put(&[d.robot, d.step])?;
        }
        match s.kind {
            StepKind::Wait { ms } if ms <= MAX_WAIT_MS => w.put(&ms.to_be_bytes())?,
            StepKind::Tc(tc) if !tc.is_empty() && tc.len() <= MAX_STEP_TC_LEN => {
                w.put(&[tc.len() as u8])?;
                w.put(tc)?;
            }
            StepKind::Wait { .. } | StepKind::Tc(_) => return Err(EmitError::Step(i)),
        }
    }
    let crc = crc32(&w.out[..w.at]);
    w.put(&crc.to_be_bytes())?;
    Ok(w.at)
}

struct Writer<'o> {
    out: &'o mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, b: &[u8]) -> Result<(), EmitError> {
        let end = self.at + b.len();
        let dst = self.out.get_mut(self.at..end).ok_or(EmitError::BufferTooSmall)?;
        dst.copy_from_slice(b);
        self.at = end;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::plan::MAX_IMAGE_LEN;

    fn deps(d: &[(u8, u8)]) -> heapless::Vec<Dep, MAX_DEPS> {
        d.iter().map(|&(robot, step)| Dep { robot, step }).collect()
    }

    fn two_steps(out: &mut [u8]) -> usize {
        let tc = [0x19, 0x01, 0xC0, 0x00, 0x00, 0x01, 0x2F, 17, 1, 0, 0, 0xAB, 0xCD];
        let steps = [
            StepRepr {
                index: 0,
                confirmed: true,
                timeout_s: 30,
                deps: deps(&[(2, 1)]),
                kind: StepKind::Tc(&tc),
            },
            StepRepr {
                index: 1,
                confirmed: false,
                timeout_s: 0,
                deps: deps(&[(1, 0)]),
                kind: StepKind::Wait { ms: 1500 },
            },
        ];
        emit(1, 0xDEAD_BEEF, &steps, out).unwrap()
    }

    // verifies: PLAN-IMG-01
    #[test]
    fn an_emitted_image_parses_back_to_the_same_steps() {
        let mut buf = [0u8; MAX_IMAGE_LEN];
        let n = two_steps(&mut buf);
        let img = Image::parse(&buf[..n]).unwrap();
        assert_eq!((img.robot, img.plan_id, img.steps()), (1, 0xDEAD_BEEF, 2));
        let s: Vec<StepView> = img.iter().collect();
        assert!(s[0].confirmed && matches!(s[0].kind, StepKind::Tc(t) if t.len() == 13));
        assert_eq!(s[0].deps.as_slice(), &[Dep { robot: 2, step: 1 }]);
        assert_eq!((s[1].kind, s[1].timeout_s), (StepKind::Wait { ms: 1500 }, 0));
        // Header (9), step 0 (1+2+1+2+1+13), step 1 (1+2+1+2+4), CRC (4).
        assert_eq!(n, 9 + 20 + 10 + 4);
    }

    // verifies: PLAN-IMG-02
    #[test]
    fn every_single_bit_flip_is_refused_as_a_checksum_error() {
        let mut buf = [0u8; MAX_IMAGE_LEN];
        let n = two_steps(&mut buf);
        for i in 0..n * 8 {
            let mut b = buf;
            b[i / 8] ^= 1 << (i % 8);
            assert!(
                matches!(Image::parse(&b[..n]), Err(ImageError::Checksum { .. })),
                "bit {i}"
            );
        }
    }

    /// Re-seals `b` with a correct CRC after an edit, to reach the format checks.
    fn reseal(b: &mut [u8]) {
        let n = b.len();
        let crc = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&crc.to_be_bytes());
    }

    // verifies: PLAN-IMG-02
    #[test]
    fn format_and_limit_violations_are_refused_with_their_reason_and_offset() {
        let mut buf = [0u8; MAX_IMAGE_LEN];
        let n = two_steps(&mut buf);
        let case = |edit: &dyn Fn(&mut Vec<u8>)| {
            let mut b = buf[..n].to_vec();
            edit(&mut b);
            reseal(&mut b);
            Image::parse(&b).unwrap_err()
        };
        assert_eq!(case(&|b| b[2] = 9), bad(invalid::FORMAT, 0));
        assert_eq!(case(&|b| b[8] = 0), bad(invalid::LIMITS, 8));
        assert_eq!(case(&|b| b[8] = 3), bad(invalid::LENGTH, n - 4));
        assert_eq!(case(&|b| b[9] |= 0x80), bad(invalid::STEP, 9));
        // A dependency of robot 1's step 1 on its own step 1 (not an earlier one).
        assert_eq!(case(&|b| b[29 + 5] = 1), bad(invalid::DEPENDENCY, 29));
        // Robot 0 named.
        assert_eq!(case(&|b| b[13] = 0), bad(invalid::DEPENDENCY, 13));
        // A byte left over after the last step.
        assert_eq!(case(&|b| b.insert(n - 4, 0)), bad(invalid::LENGTH, n - 4));
        assert_eq!(Image::parse(&buf[..5]).unwrap_err(), bad(invalid::LENGTH, 5));
    }

    proptest::proptest! {
        // verifies: PLAN-IMG-02
        #[test]
        fn random_bytes_never_panic_the_parser(b in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..300)) {
            let _ = Image::parse(&b);
            let mut s = b.clone();
            if s.len() >= 4 { reseal(&mut s); }
            if let Ok(img) = Image::parse(&s) { for st in img.iter() { let _ = st; } }
        }
    }
}
