//! Parameter types, calibrations and limits.

/// On-the-wire type of a parameter or argument. All multi-byte values are big-endian.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PType {
    Bool,
    U8,
    U16,
    U32,
    I16,
    I32,
}

impl PType {
    /// Size in bytes on the wire.
    pub const fn size(self) -> usize {
        match self {
            PType::Bool | PType::U8 => 1,
            PType::U16 | PType::I16 => 2,
            PType::U32 | PType::I32 => 4,
        }
    }
    /// Size in bits on the wire.
    pub const fn bits(self) -> usize {
        self.size() * 8
    }
    pub const fn signed(self) -> bool {
        matches!(self, PType::I16 | PType::I32)
    }
    /// Name used in the ICD and JSON export.
    pub const fn name(self) -> &'static str {
        match self {
            PType::Bool => "bool",
            PType::U8 => "u8",
            PType::U16 => "u16",
            PType::U32 => "u32",
            PType::I16 => "i16",
            PType::I32 => "i32",
        }
    }
    /// Smallest raw value the type holds.
    pub const fn min(self) -> i64 {
        match self {
            PType::Bool | PType::U8 | PType::U16 | PType::U32 => 0,
            PType::I16 => i16::MIN as i64,
            PType::I32 => i32::MIN as i64,
        }
    }
    /// Largest raw value the type holds.
    pub const fn max(self) -> i64 {
        match self {
            PType::Bool => 1,
            PType::U8 => u8::MAX as i64,
            PType::U16 => u16::MAX as i64,
            PType::U32 => u32::MAX as i64,
            PType::I16 => i16::MAX as i64,
            PType::I32 => i32::MAX as i64,
        }
    }
    /// The value `raw` is sent as: saturated to the type's range, a boolean `raw != 0`
    /// (the wire crate's typed `from_values` does the same).
    pub const fn saturate(self, raw: i64) -> i64 {
        match self {
            PType::Bool => (raw != 0) as i64,
            _ => {
                if raw < self.min() {
                    self.min()
                } else if raw > self.max() {
                    self.max()
                } else {
                    raw
                }
            }
        }
    }
    /// Writes `raw` ([`Self::saturate`]d) into `buf[..size]`.
    /// Returns `None` if `buf` is too short.
    pub fn encode(self, raw: i64, buf: &mut [u8]) -> Option<usize> {
        let n = self.size();
        let out = buf.get_mut(..n)?;
        let v = self.saturate(raw);
        match self {
            PType::Bool | PType::U8 => out[0] = v as u8,
            PType::U16 => out.copy_from_slice(&(v as u16).to_be_bytes()),
            PType::I16 => out.copy_from_slice(&(v as i16).to_be_bytes()),
            PType::U32 => out.copy_from_slice(&(v as u32).to_be_bytes()),
            PType::I32 => out.copy_from_slice(&(v as i32).to_be_bytes()),
        }
        Some(n)
    }
    /// Reads a raw value from `buf[..size]`; `None` if `buf` is too short.
    pub fn decode(self, buf: &[u8]) -> Option<i64> {
        let b = buf.get(..self.size())?;
        Some(match self {
            PType::Bool | PType::U8 => b[0] as i64,
            PType::U16 => u16::from_be_bytes([b[0], b[1]]) as i64,
            PType::I16 => i16::from_be_bytes([b[0], b[1]]) as i64,
            PType::U32 => u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as i64,
            PType::I32 => i32::from_be_bytes([b[0], b[1], b[2], b[3]]) as i64,
        })
    }
}

/// Free text of a MIB table entry (description, hazard reason): `s` with feature
/// `descriptions` (implied by `std`), `""` without, so that a no_std image that never
/// shows the text does not store it. Only names, units and numbers are in every build.
#[inline(always)]
pub const fn text(s: &'static str) -> Text {
    #[cfg(feature = "descriptions")]
    return s;
    #[cfg(not(feature = "descriptions"))]
    {
        let _ = s;
        NoText
    }
}

/// [`text`] as a string (`""` without feature `descriptions`).
#[inline(always)]
pub const fn text_str(s: &'static str) -> &'static str {
    if cfg!(feature = "descriptions") {
        s
    } else {
        ""
    }
}

/// The type of a table entry's free text: `&'static str` with feature `descriptions`,
/// the empty [`NoText`] without, so that the entries of a no_std image carry not even
/// the pointer.
#[cfg(feature = "descriptions")]
pub type Text = &'static str;
#[cfg(not(feature = "descriptions"))]
pub type Text = NoText;

/// Free text left out of this build (feature `descriptions` off).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct NoText;

/// Linear raw → engineering calibration: `eng = raw * scale + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calib {
    pub scale: f64,
    pub offset: f64,
}

impl Calib {
    /// No calibration (engineering value equals raw value).
    pub const IDENTITY: Calib = Calib {
        scale: 1.0,
        offset: 0.0,
    };
    pub const fn new(scale: f64, offset: f64) -> Self {
        Calib { scale, offset }
    }
    pub const fn is_identity(&self) -> bool {
        self.scale == 1.0 && self.offset == 0.0
    }
    pub fn eng(&self, raw: i64) -> f64 {
        raw as f64 * self.scale + self.offset
    }
    /// Raw value nearest to an engineering value (usable in `const` tables).
    pub const fn raw(&self, eng: f64) -> i64 {
        let r = (eng - self.offset) / self.scale;
        if r >= 0.0 {
            (r + 0.5) as i64
        } else {
            (r - 0.5) as i64
        }
    }
}

/// Calibrations are constants of the MIB and never NaN, so equality is total.
impl Eq for Calib {}

/// Out-of-limit bands in engineering units (ground display; SCOS `ocf`/`ocp`).
/// Soft limits warn, hard limits alarm. The on-board monitors (PUS 12) use the
/// hard limits of the same parameter, converted to raw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    pub soft_lo: f64,
    pub soft_hi: f64,
    pub hard_lo: f64,
    pub hard_hi: f64,
}
