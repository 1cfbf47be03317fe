//! On-board parameters tunable by PUS 20 (thresholds and gains that are not PUS 12
//! monitor limits). Values are i32 in the unit given.

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TunableDef {
    pub id: u16,
    pub name: &'static str,
    pub unit: &'static str,
    pub default: i32,
    pub min: i32,
    pub max: i32,
    pub desc: crate::types::Text,
}

macro_rules! tunables {
    ($( $name:ident = $id:literal, $unit:literal, $def:expr, $min:expr, $max:expr, $desc:literal; )*) => {
        /// Tunable IDs by mnemonic.
        pub mod tid { $( #[doc = $desc] pub const $name: u16 = $id; )* }
        pub const TUNABLES: &[TunableDef] = &[ $( TunableDef {
            id: $id, name: stringify!($name), unit: $unit, default: $def, min: $min, max: $max, desc: $crate::types::text($desc),
        }, )* ];
    };
}

tunables! {
    BOLT_PUSH_THRESHOLD_MA = 1, "mA", 1200, 200, 2400, "Bolter current that ends a push (fastener reached)";
    BOLT_LOCK_THRESHOLD_MA = 2, "mA", 1800, 400, 2450, "Bolter current that means the fastener pair is locked";
    BOLT_MAX_ATTEMPTS = 3, "", 3, 1, 5, "Attempts per fastener pair before a bolting failure";
    BOLT_STEP_TIMEOUT_MS = 4, "ms", 4000, 500, 20000, "Longest bolter state before the attempt fails";
    B_ACK_TIMEOUT_MS = 5, "ms", 60, 10, 1000, "Wait for board B's acknowledgement before resending";
    B_MAX_RETRIES = 6, "", 3, 1, 10, "Resends of a command to board B before communication loss";
    HIP_KP_VEL = 7, "1e-3", 800, 0, 10000, "Hip velocity PI proportional gain";
    HIP_KI_VEL = 8, "1e-3", 200, 0, 10000, "Hip velocity PI integral gain";
    HIP_KP_POS = 9, "1e-3", 1500, 0, 10000, "Hip position PI proportional gain";
    HIP_KI_POS = 10, "1e-3", 300, 0, 10000, "Hip position PI integral gain";
    PRIMITIVE_TIMEOUT_MS = 11, "ms", 30000, 1000, 120000, "Longest motion primitive before it fails";
    ARM_SWITCH_WAIT_MS = 12, "ms", 2500, 50, 10000, "Time after the contract command reaches the servo for the arm switch to close: a full stroke at servo speed (2 s) plus margin, since an arm that was held back (stuck, blocked) lags the open-loop command by up to a stroke";
}

pub fn by_id(id: u16) -> Option<&'static TunableDef> {
    TUNABLES.iter().find(|t| t.id == id)
}

pub fn by_name(name: &str) -> Option<&'static TunableDef> {
    TUNABLES.iter().find(|t| t.name.eq_ignore_ascii_case(name))
}

#[cfg(test)]
mod tests {
    use super::*;
    // verifies: PUS-20-01
    #[test]
    fn defaults_in_range_ids_unique() {
        for (i, t) in TUNABLES.iter().enumerate() {
            assert!(t.min <= t.default && t.default <= t.max, "{}", t.name);
            assert!(TUNABLES[i + 1..].iter().all(|o| o.id != t.id));
        }
    }
}
