//! Current values of the PUS 20 tunables (`mib::tunables`), defaults at boot.

use mib::tunables::{TunableDef, TUNABLES};

const N: usize = TUNABLES.len();

/// Why a tunable could not be set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TunableError {
    Unknown(u16),
    OutOfRange { id: u16, value: i32 },
}

impl core::fmt::Display for TunableError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TunableError::Unknown(id) => write!(f, "unknown tunable {id}"),
            TunableError::OutOfRange { id, value } => {
                write!(f, "value {value} out of range for tunable {id}")
            }
        }
    }
}

impl core::error::Error for TunableError {}

/// The tunable table.
#[derive(Clone, Debug)]
pub struct Tunables {
    vals: [i32; N],
}

impl Default for Tunables {
    fn default() -> Self {
        let mut vals = [0; N];
        for (v, d) in vals.iter_mut().zip(TUNABLES.iter()) {
            *v = d.default;
        }
        Tunables { vals }
    }
}

fn index(id: u16) -> Option<(usize, &'static TunableDef)> {
    TUNABLES.iter().enumerate().find(|(_, d)| d.id == id)
}

impl Tunables {
    /// Value of a tunable (its MIB default if the ID is unknown to this table, which
    /// cannot happen for IDs taken from `mib::tunables::tid`).
    pub fn get(&self, id: u16) -> i32 {
        index(id).map(|(i, _)| self.vals[i]).unwrap_or(0)
    }
    pub fn try_get(&self, id: u16) -> Option<i32> {
        index(id).map(|(i, _)| self.vals[i])
    }
    pub fn set(&mut self, id: u16, value: i32) -> Result<(), TunableError> {
        let (i, d) = index(id).ok_or(TunableError::Unknown(id))?;
        if value < d.min || value > d.max {
            return Err(TunableError::OutOfRange { id, value });
        }
        self.vals[i] = value;
        Ok(())
    }
    /// A tunable as an unsigned duration or count (negative values read as 0).
    pub fn get_u32(&self, id: u16) -> u32 {
        self.get(id).max(0) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mib::tunables::tid;
    // verifies: PUS-20-01
    #[test]
    fn tunables_start_at_mib_defaults_and_reject_out_of_range() {
        let mut t = Tunables::default();
        assert_eq!(t.get(tid::BOLT_MAX_ATTEMPTS), 3);
        assert_eq!(
            t.set(tid::BOLT_MAX_ATTEMPTS, 99),
            Err(TunableError::OutOfRange {
                id: tid::BOLT_MAX_ATTEMPTS,
                value: 99
            })
        );
        assert_eq!(t.set(999, 1), Err(TunableError::Unknown(999)));
        t.set(tid::BOLT_MAX_ATTEMPTS, 2).unwrap();
        assert_eq!(t.get(tid::BOLT_MAX_ATTEMPTS), 2);
    }
}
