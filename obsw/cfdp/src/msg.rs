//! Reserved CFDP messages to user (727.0-B-5 § 6.2, 6.3): the value of a message-to-user
//! TLV that starts with `"cfdp"` and a message type. The ones this entity takes:
//! Proxy Put Request (0x00, with an optional Proxy Transmission Mode, 0x04) and Directory
//! Listing Request (0x10). Parsed from untrusted bytes: every length is checked.

use crate::entity::Class;

const MAGIC: &[u8; 4] = b"cfdp";
const PROXY_PUT_REQUEST: u8 = 0x00;
const PROXY_TRANSMISSION_MODE: u8 = 0x04;
const DIRECTORY_LISTING_REQUEST: u8 = 0x10;

/// A reserved message this entity acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReservedMsg<'a> {
    /// Send `src` of this entity's store to entity `to` as `dest` (a `get` from the peer).
    ProxyPut {
        to: u64,
        src: &'a str,
        dest: &'a str,
        class: Class,
    },
    /// List `dir` into the file `dest` and send it to the requester.
    DirectoryListing { dir: &'a str, dest: &'a str },
}

/// One LV (length byte, value) from `b`: the value and the rest.
fn lv(b: &[u8]) -> Option<(&[u8], &[u8])> {
    let (&n, rest) = b.split_first()?;
    let n = n as usize;
    (rest.len() >= n).then(|| rest.split_at(n))
}

fn lv_str(b: &[u8]) -> Option<(&str, &[u8])> {
    let (v, rest) = lv(b)?;
    Some((core::str::from_utf8(v).ok()?, rest))
}

/// The reserved message in a message-to-user value, if it is one this entity takes.
/// A Proxy Put Request may be followed by its Proxy Transmission Mode in the same value
/// (this entity writes them so; the standard's separate TLV is honoured by the caller).
pub fn parse(v: &[u8]) -> Option<ReservedMsg<'_>> {
    let rest = v.strip_prefix(MAGIC)?;
    let (&kind, rest) = rest.split_first()?;
    match kind {
        PROXY_PUT_REQUEST => {
            let (id, rest) = lv(rest)?;
            if id.is_empty() || id.len() > 8 {
                return None;
            }
            let to = id.iter().fold(0u64, |a, b| (a << 8) | *b as u64);
            let (src, rest) = lv_str(rest)?;
            let (dest, rest) = lv_str(rest)?;
            let class = match rest {
                [] => Class::Two,
                [m0, m1, m2, m3, PROXY_TRANSMISSION_MODE, mode] if [*m0, *m1, *m2, *m3] == *MAGIC => {
                    if mode & 1 == 1 {
                        Class::One
                    } else {
                        Class::Two
                    }
                }
                _ => return None,
            };
            Some(ReservedMsg::ProxyPut { to, src, dest, class })
        }
        DIRECTORY_LISTING_REQUEST => {
            let (dir, rest) = lv_str(rest)?;
            let (dest, rest) = lv_str(rest)?;
            rest.is_empty().then_some(ReservedMsg::DirectoryListing { dir, dest })
        }
        _ => None,
    }
}

fn put_lv(out: &mut [u8], at: &mut usize, v: &[u8]) -> Option<()> {
    let n = u8::try_from(v.len()).ok()?;
    *out.get_mut(*at)? = n;
    out.get_mut(*at + 1..*at + 1 + v.len())?.copy_from_slice(v);
    *at += 1 + v.len();
    Some(())
}

/// The class of a Proxy Transmission Mode message sent as a message of its own (727.0-B-5
/// § 6.2.4, the way Yamcs sends it beside its Proxy Put Request).
pub fn proxy_transmission_mode(v: &[u8]) -> Option<Class> {
    match v {
        [m0, m1, m2, m3, PROXY_TRANSMISSION_MODE, mode] if [*m0, *m1, *m2, *m3] == *MAGIC => {
            Some(if mode & 1 == 1 { Class::One } else { Class::Two })
        }
        _ => None,
    }
}

/// Writes a Proxy Put Request (send `src` to entity `to` as `dest` in `class`) into `out`.
pub fn proxy_put(out: &mut [u8], to: u16, src: &str, dest: &str, class: Class) -> Option<usize> {
    out.get_mut(..5)?.copy_from_slice(b"cfdp\x00");
    let mut at = 5;
    put_lv(out, &mut at, &to.to_be_bytes())?;
    put_lv(out, &mut at, src.as_bytes())?;
    put_lv(out, &mut at, dest.as_bytes())?;
    if class == Class::One {
        out.get_mut(at..at + 6)?.copy_from_slice(b"cfdp\x04\x01");
        at += 6;
    }
    Some(at)
}

/// Writes a Directory Listing Request (list `dir` into `dest`) into `out`.
pub fn directory_listing(out: &mut [u8], dir: &str, dest: &str) -> Option<usize> {
    out.get_mut(..5)?.copy_from_slice(b"cfdp\x10");
    let mut at = 5;
    put_lv(out, &mut at, dir.as_bytes())?;
    put_lv(out, &mut at, dest.as_bytes())?;
    Some(at)
}

#[cfg(test)]
mod tests {
    use super::*;

    // verifies: FILE-CFDP-03
    #[test]
    fn reserved_messages_round_trip_and_truncations_are_refused() {
        let mut b = [0u8; 64];
        let n = proxy_put(&mut b, 0, "log.bin", "log-r1.bin", Class::One).unwrap();
        assert_eq!(
            parse(&b[..n]),
            Some(ReservedMsg::ProxyPut {
                to: 0,
                src: "log.bin",
                dest: "log-r1.bin",
                class: Class::One
            })
        );
        for k in 0..n {
            // Cut just before the transmission mode message: a class 2 request.
            let expect = (k == n - 6).then_some(ReservedMsg::ProxyPut {
                to: 0,
                src: "log.bin",
                dest: "log-r1.bin",
                class: Class::Two,
            });
            assert_eq!(parse(&b[..k]), expect, "truncated to {k}");
        }
        let n = directory_listing(&mut b, "/", "dir.lst").unwrap();
        assert_eq!(
            parse(&b[..n]),
            Some(ReservedMsg::DirectoryListing {
                dir: "/",
                dest: "dir.lst"
            })
        );
        assert_eq!(parse(b"cfdq\x10\x01/\x01x"), None);
        assert_eq!(parse(b"cfdp\x07"), None, "a type this entity does not take");
    }

    // verifies: FILE-CFDP-03
    #[test]
    fn a_proxy_transmission_mode_of_its_own_gives_the_class() {
        assert_eq!(proxy_transmission_mode(b"cfdp\x04\x01"), Some(Class::One));
        assert_eq!(proxy_transmission_mode(b"cfdp\x04\x00"), Some(Class::Two));
        assert_eq!(proxy_transmission_mode(b"cfdp\x04"), None);
        assert_eq!(proxy_transmission_mode(b"cfdp\x04\x01\x00"), None);
        assert_eq!(proxy_transmission_mode(b"cfdq\x04\x01"), None);
    }
}
