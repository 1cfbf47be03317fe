//! Service 213, software update in flight (docs/update.md): the update component, its state
//! and its contract, composed by the obsw.
//!
//! - **Takes** TCs UPDATE_INSTALL (a file of the store into the inactive slot, verified
//!   there), UPDATE_ACTIVATE (hazardous: the verified image, named by its SHA-256, becomes the
//!   one that boots; then a reset) and UPDATE_CONFIRM; every refusal a MIB failure code,
//!   counted in UPDATE_REFUSALS.
//! - **Supplies** the parameters of source `Update` (running version and slot, last outcome,
//!   installed version, refusals) and the UPDATE_* events.
//! - **Needs** a platform ([`Slots`]): its otadata and slot flashes, the store's files, the
//!   ground's update key and its own part of the self-test. Without one (a lab run without
//!   the boot launcher) every update TC is refused UPDATE_UNAVAILABLE.
//!
//! At start ([`Update::boot`]) the component reads otadata as the running image sees it. An
//! image started for the first time (PENDING_VERIFY) runs its self-test — its own slot must
//! verify (digest and signature) and the platform's checks pass — and confirms itself, or
//! asks for a reset unconfirmed, after which the boot returns to the previous image.

#[cfg(feature = "update")]
use mib::update::outcome;
use mib::update::DIGEST_LEN;
use mib_wire::{ev, Failure as W};
#[cfg(feature = "update")]
use mmic_update::flash::Flash;
#[cfg(feature = "update")]
use mmic_update::image::{self, Header, Refusal, UpdateKey};
#[cfg(feature = "update")]
use mmic_update::otadata::{self, OtaState};

use crate::accept::Tc;
use crate::downlink::Downlink;
use crate::failure::Failure;
use crate::request::unknown;
use crate::services::{Component, Contract};
use crate::tm::{TmSink, TmStore};
use mib::params::{pid, NotSupplied, Source, Supplied};
use mib::tc::service;

/// What a platform gives the update component.
#[cfg(feature = "update")]
pub trait Slots {
    /// The target its images must be for (`mib::update::target`).
    fn target(&self) -> u8;
    /// The ground's update key (`None`: the robot holds none, nothing is installed).
    fn key(&self) -> Option<UpdateKey>;
    /// The otadata partition.
    fn otadata(&mut self) -> &mut dyn Flash;
    /// Application slot `n` (0 or 1).
    fn slot(&mut self, n: u8) -> &mut dyn Flash;
    /// Copies the store's file `name` into slot `n` and verifies it there
    /// (`mmic_update::image::install`); `Refusal::NoFile` for a name the store does not hold.
    fn install(&mut self, name: &[u8], n: u8, key: &UpdateKey) -> Result<Header, Refusal>;
    /// The platform's own start-up checks (its stores and links came up): `Err(check)` with
    /// a code of its own (> 1) when one failed.
    fn self_test(&mut self) -> Result<(), u8>;
}

/// Self-test check code: the running image's own slot does not verify.
#[cfg(feature = "update")]
pub const CHECK_OWN_IMAGE: u8 = 1;

/// A platform's slots, held for the whole run (a static on board, leaked once on the host).
#[cfg(feature = "update")]
pub type SlotsRef = &'static mut (dyn Slots + Send);

/// A PUS 213 request.
#[derive(Clone, Copy, Debug)]
pub enum Request<'a> {
    Install { name: &'a [u8] },
    Activate { digest: [u8; DIGEST_LEN] },
    Confirm,
}

impl<'a> Request<'a> {
    pub fn parse(tc: &Tc<'a>) -> Result<Self, Failure> {
        use mib::update::sub;
        Ok(match tc.subservice {
            sub::INSTALL => {
                let a = mib_wire::args::UpdateInstall::of(&tc.args);
                if tc.rest.len() != usize::from(a.name_len) {
                    return Err(Failure::bad_arg_length(
                        tc.def.fixed_len() + tc.rest.len(),
                        tc.def.fixed_len() + usize::from(a.name_len),
                    ));
                }
                Request::Install { name: tc.rest }
            }
            sub::ACTIVATE => {
                let a = mib_wire::args::UpdateActivate::of(&tc.args);
                let words = [
                    a.digest_0, a.digest_1, a.digest_2, a.digest_3, a.digest_4, a.digest_5, a.digest_6, a.digest_7,
                ];
                let mut digest = [0; DIGEST_LEN];
                for (d, w) in digest.chunks_exact_mut(4).zip(words) {
                    d.copy_from_slice(&w.to_be_bytes());
                }
                Request::Activate { digest }
            }
            sub::CONFIRM => Request::Confirm,
            _ => return Err(unknown(tc)),
        })
    }
}

/// The image running, as the boot found it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunningImage {
    pub slot: u8,
    /// Version and digest of the slot's image (`None`: the slot does not hold a verified one).
    pub version: u32,
    pub digest: Option<[u8; DIGEST_LEN]>,
}

/// An event the component asks the obsw to raise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Note {
    Installed { version: u32, length: u32, slot: u8 },
    Refused { reason: u8, refusals: u32 },
    Activated { version: u32, slot: u8 },
    Confirmed { version: u32, slot: u8 },
    SelfTestFailed { version: u32, check: u8 },
    RolledBack { aborted_slot: u8, version: u32 },
}

/// The update component.
#[derive(Default)]
pub struct Update {
    #[cfg(feature = "update")]
    slots: Option<SlotsRef>,
    running: RunningImage,
    /// The verified image waiting in the inactive slot.
    #[cfg(feature = "update")]
    installed: Option<Header>,
    /// The image activated by this run (a second activation of it is stale).
    #[cfg(feature = "update")]
    activated: Option<[u8; DIGEST_LEN]>,
    outcome: u8,
    refusals: u32,
    reset: bool,
}

impl core::fmt::Debug for Update {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Update")
            .field("running", &self.running)
            .field("installed", &self.installed_version())
            .field("outcome", &self.outcome)
            .field("refusals", &self.refusals)
            .finish()
    }
}

impl Update {
    /// The platform must reset (after this period's TM is out): an activation, or a
    /// self-test that failed.
    pub fn reset_requested(&self) -> bool {
        self.reset
    }

    pub fn running(&self) -> RunningImage {
        self.running
    }

    /// The refusal every update TC gets from an obsw without slots.
    fn unavailable(&mut self) -> Failure {
        self.refusals = self.refusals.wrapping_add(1);
        Failure(W::UpdateUnavailable {})
    }

    /// The parameters the MIB names this component the source of.
    pub fn param(&self, id: u16) -> Supplied {
        Ok(Some(match id {
            pid::SW_VERSION => i64::from(self.running.version),
            pid::SW_SLOT => i64::from(self.running.slot),
            pid::UPDATE_OUTCOME => i64::from(self.outcome),
            pid::UPDATE_INSTALLED_VERSION => i64::from(self.installed_version()),
            pid::UPDATE_REFUSALS => i64::from(self.refusals),
            _ => return Err(NotSupplied(id)),
        }))
    }
}

/// An obsw built without the `update` feature (board A: no file store to install an image
/// from, and Ed25519 and SHA-256 would take about 113 KB of its image) has no slots: every
/// update TC is refused UPDATE_UNAVAILABLE and counted, as on a host without its launcher.
#[cfg(not(feature = "update"))]
impl Update {
    fn installed_version(&self) -> u32 {
        0
    }

    /// Refuses the request: there are no slots to act on.
    pub fn request(&mut self, _r: Request, _note: &mut impl FnMut(Note)) -> Result<(), Failure> {
        Err(self.unavailable())
    }
}

#[cfg(feature = "update")]
impl Update {
    fn installed_version(&self) -> u32 {
        self.installed.map_or(0, |h| h.version)
    }

    /// Gives the component its platform's slots.
    pub fn attach(&mut self, slots: SlotsRef) {
        self.slots = Some(slots);
    }

    fn inactive(&self) -> u8 {
        1 - self.running.slot.min(1)
    }

    /// Reads otadata as the running image sees it and runs the self-test of an image started
    /// for the first time; the events to raise go to `note`.
    pub fn boot(&mut self, note: &mut impl FnMut(Note)) {
        let Some(s) = self.slots.as_deref_mut() else { return };
        let Ok(run) = otadata::running(s.otadata()) else {
            return;
        };
        let target = s.target();
        let key = s.key();
        let verified = key.and_then(|k| image::verify_slot(s.slot(run.slot), &k, target).ok());
        self.running = RunningImage {
            slot: run.slot,
            version: verified.map_or(0, |h| h.version),
            digest: verified.map(|h| h.digest),
        };
        if let Some(aborted_slot) = run.rolled_back_from {
            self.outcome = outcome::ROLLED_BACK;
            note(Note::RolledBack {
                aborted_slot,
                version: self.running.version,
            });
        }
        if run.state != Some(OtaState::PendingVerify) {
            return;
        }
        self.outcome = outcome::PENDING;
        let check = if verified.is_none() {
            Err(CHECK_OWN_IMAGE)
        } else {
            s.self_test()
        };
        let version = self.running.version;
        match check {
            Ok(()) => {
                if otadata::confirm(s.otadata()).is_ok() {
                    self.outcome = outcome::CONFIRMED;
                    note(Note::Confirmed {
                        version,
                        slot: run.slot,
                    });
                }
            }
            Err(check) => {
                note(Note::SelfTestFailed { version, check });
                self.reset = true;
            }
        }
    }

    fn refuse(&mut self, f: W) -> Failure {
        self.refusals = self.refusals.wrapping_add(1);
        Failure(f)
    }

    /// Executes a request; `note` receives the events to raise.
    pub fn request(&mut self, r: Request, note: &mut impl FnMut(Note)) -> Result<(), Failure> {
        let inactive = self.inactive();
        let Some(s) = self.slots.as_deref_mut() else {
            return Err(self.unavailable());
        };
        match r {
            Request::Install { name } => {
                let result = match s.key() {
                    None => Err(Refusal::NoKey),
                    Some(k) => s.install(name, inactive, &k),
                };
                match result {
                    Ok(h) => {
                        self.installed = Some(h);
                        self.outcome = outcome::INSTALLED;
                        note(Note::Installed {
                            version: h.version,
                            length: h.length,
                            slot: inactive,
                        });
                        Ok(())
                    }
                    Err(why) => {
                        // Whatever was in the inactive slot is gone or unverified now.
                        self.installed = None;
                        self.outcome = outcome::REFUSED;
                        let reason = why.code();
                        let f = self.refuse(W::UpdateImageRefused { reason });
                        note(Note::Refused {
                            reason,
                            refusals: self.refusals,
                        });
                        Err(f)
                    }
                }
            }
            Request::Activate { digest } => {
                let stale = self.activated == Some(digest) || self.running.digest == Some(digest);
                if stale {
                    let version = self.installed.map_or(self.running.version, |h| h.version);
                    return Err(self.refuse(W::UpdateStaleActivation { version }));
                }
                let Some(h) = self.installed else {
                    return Err(self.refuse(W::UpdateNotInstalled {}));
                };
                if h.digest != digest {
                    return Err(self.refuse(W::UpdateWrongImage {
                        installed_version: h.version,
                    }));
                }
                // The slot again, as it is now: what boots is what was verified.
                let target = s.target();
                let again = match s.key() {
                    Some(k) => image::verify_slot(s.slot(inactive), &k, target),
                    None => Err(Refusal::NoKey),
                };
                match again {
                    Ok(now) if now.digest == digest => {}
                    Ok(_) => {
                        return Err(self.refuse(W::UpdateSlotChanged {
                            reason: Refusal::Digest.code(),
                        }))
                    }
                    Err(why) => return Err(self.refuse(W::UpdateSlotChanged { reason: why.code() })),
                }
                if otadata::activate(s.otadata(), inactive).is_err() {
                    return Err(self.refuse(W::UpdateSlotChanged {
                        reason: Refusal::Flash.code(),
                    }));
                }
                self.activated = Some(digest);
                self.installed = None;
                self.outcome = outcome::PENDING;
                self.reset = true;
                note(Note::Activated {
                    version: h.version,
                    slot: inactive,
                });
                Ok(())
            }
            Request::Confirm => match otadata::running(s.otadata()) {
                Ok(r) if r.state == Some(OtaState::PendingVerify) && r.slot == self.running.slot => {
                    if otadata::confirm(s.otadata()).is_err() {
                        return Err(self.refuse(W::UpdateNothingToConfirm {}));
                    }
                    self.outcome = outcome::CONFIRMED;
                    note(Note::Confirmed {
                        version: self.running.version,
                        slot: self.running.slot,
                    });
                    Ok(())
                }
                _ => Err(self.refuse(W::UpdateNothingToConfirm {})),
            },
        }
    }
}

impl Update {
    /// [`Update::boot`] with what it found reported through the downlink (the obsw's
    /// `update_boot`).
    #[cfg(feature = "update")]
    pub(crate) fn boot_reported<S: TmStore>(&mut self, now: u64, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
        self.boot(&mut |n| report(now, n, dl, sink));
    }
}

/// [`Update::request`] with its events raised through the downlink.
impl Component for Update {
    const CONTRACT: Contract = Contract::new("update", Some(service::UPDATE), &[Source::Update]);
    type Request<'a> = Request<'a>;
    type Output = ();
    fn handle<S: TmStore>(
        &mut self,
        now: u64,
        r: Request<'_>,
        dl: &mut Downlink<S>,
        sink: &mut impl TmSink,
    ) -> Result<(), Failure> {
        self.request(r, &mut |n| report(now, n, dl, sink))
    }
}

/// The event of a note.
fn report<S: TmStore>(now: u64, n: Note, dl: &mut Downlink<S>, sink: &mut impl TmSink) {
    match n {
        Note::Installed { version, length, slot } => dl.raise(now, ev::UpdateInstalled { version, length, slot }, sink),
        Note::Refused { reason, refusals } => dl.raise(now, ev::UpdateRefused { reason, refusals }, sink),
        Note::Activated { version, slot } => dl.raise(now, ev::UpdateActivated { version, slot }, sink),
        Note::Confirmed { version, slot } => dl.raise(now, ev::UpdateConfirmed { version, slot }, sink),
        Note::SelfTestFailed { version, check } => dl.raise(now, ev::UpdateSelfTestFailed { version, check }, sink),
        Note::RolledBack { aborted_slot, version } => {
            dl.raise(now, ev::UpdateRolledBack { aborted_slot, version }, sink)
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::vec::Vec;

    /// One failure of each code the component reports, as it makes them.
    pub(crate) fn every_failure() -> Vec<Failure> {
        [
            W::UpdateImageRefused { reason: 7 },
            W::UpdateNotInstalled {},
            W::UpdateWrongImage { installed_version: 1 },
            W::UpdateStaleActivation { version: 1 },
            W::UpdateNothingToConfirm {},
            W::UpdateSlotChanged { reason: 6 },
            W::UpdateUnavailable {},
        ]
        .into_iter()
        .map(Failure)
        .collect()
    }

    // The host-side twin of the QEMU test of UPD-SVC-04 (firmware/qemu-tests, t_obsw),
    // run with `cargo test -p obsw-core --no-default-features`.
    #[cfg(not(feature = "update"))]
    #[test]
    fn an_obsw_built_without_update_refuses_every_update_tc_unavailable_counted_and_evented() {
        use crate::obsw::tests::{failure, kind, obsw, of, send};
        use mib::events::eid;
        use mib::tc::service::UPDATE;
        use mib::update::sub;
        let mut o = obsw();
        let requests: [(u8, &[u8]); 3] = [
            (sub::INSTALL, &[3, b'a', b'.', b'b']),
            (sub::ACTIVATE, &[7; 32]),
            (sub::CONFIRM, &[]),
        ];
        for (n, (sub, app)) in requests.into_iter().enumerate() {
            let p = send(&mut o, 10 * (n as u64 + 1), n as u16 + 1, UPDATE, sub, app);
            let failed: Vec<_> = p
                .iter()
                .filter(|p| kind(p).0 == 1 && kind(p).1.is_multiple_of(2))
                .collect();
            assert_eq!(failed.len(), 1, "one failure report for subservice {sub}");
            assert_eq!(failure(failed[0]).0, mib::FailureCode::UPDATE_UNAVAILABLE.code());
            let rejected = (1..=4)
                .flat_map(|s| of(&p, 5, s))
                .any(|e| u16::from_be_bytes([kind(&e).2[0], kind(&e).2[1]]) == eid::TC_REJECTED);
            assert!(rejected, "TC_REJECTED for subservice {sub}");
        }
        assert_eq!(o.param::<{ pid::UPDATE_REFUSALS }>(), 3);
    }

    #[cfg(feature = "update")]
    mod with_slots {
        use super::super::*;
        use crate::obsw::tests::{failure, kind, obsw, of, send, TestObsw};
        use mib::events::eid;
        use mib::tc::service::UPDATE;
        use mib::update::{sub, target, HEADER_LEN};
        use mmic_update::flash::RamNor;
        use std::boxed::Box;
        use std::vec::Vec;

        const SECRET: [u8; 32] = [0x42; 32];
        const SLOT: usize = 64 * 1024;

        /// Slots in RAM, and a file store of one file.
        #[derive(Clone)]
        struct RamSlots {
            ota: RamNor<8192>,
            slots: [RamNor<SLOT>; 2],
            file: Vec<u8>,
            fail_self_test: bool,
        }

        impl Slots for RamSlots {
            fn target(&self) -> u8 {
                target::HOST
            }
            fn key(&self) -> Option<UpdateKey> {
                UpdateKey::from_bytes(&image::public_key(&SECRET))
            }
            fn otadata(&mut self) -> &mut dyn Flash {
                &mut self.ota
            }
            fn slot(&mut self, n: u8) -> &mut dyn Flash {
                &mut self.slots[usize::from(n)]
            }
            fn install(&mut self, name: &[u8], n: u8, key: &UpdateKey) -> Result<Header, Refusal> {
                if name != b"new.img" {
                    return Err(Refusal::NoFile);
                }
                image::install(&mut &self.file[..], &mut self.slots[usize::from(n)], key, target::HOST)
            }
            fn self_test(&mut self) -> Result<(), u8> {
                if self.fail_self_test {
                    Err(2)
                } else {
                    Ok(())
                }
            }
        }

        fn signed(version: u32, fill: u8) -> Vec<u8> {
            let payload = std::vec![fill; 3000];
            let mut v = image::sign(&SECRET, version, target::HOST, &payload).unwrap().to_vec();
            v.extend_from_slice(&payload);
            v
        }

        /// Slots with version 1.0.0 in slot 0 (otadata erased: slot 0 boots) and `file` in the store.
        fn slots(file: Vec<u8>) -> &'static mut RamSlots {
            let mut s = Box::new(RamSlots {
                ota: RamNor::new(),
                slots: [RamNor::new(), RamNor::new()],
                file: signed(0x010000, 1),
                fail_self_test: false,
            });
            let first = s.file.clone();
            let key = s.key().unwrap();
            image::install(&mut &first[..], &mut s.slots[0], &key, target::HOST).unwrap();
            s.file = file;
            Box::leak(s)
        }

        fn install_tc(name: &[u8]) -> Vec<u8> {
            let mut app = std::vec![name.len() as u8];
            app.extend_from_slice(name);
            app
        }

        fn activate_tc(digest: &[u8]) -> Vec<u8> {
            digest.to_vec()
        }

        fn failed_with(pkts: &[Vec<u8>]) -> Option<u16> {
            pkts.iter()
                .find(|p| kind(p).0 == 1 && kind(p).1.is_multiple_of(2))
                .map(|p| failure(p).0)
        }

        fn events(pkts: &[Vec<u8>]) -> Vec<u16> {
            of(pkts, 5, 0)
                .into_iter()
                .chain((1..=4).flat_map(|s| of(pkts, 5, s)))
                .map(|p| u16::from_be_bytes([kind(&p).2[0], kind(&p).2[1]]))
                .collect()
        }

        fn booted(s: &'static mut RamSlots) -> (TestObsw, Vec<Vec<u8>>) {
            let mut o = obsw();
            o.update.attach(s);
            let mut sink = Vec::new();
            o.update_boot(0, &mut sink);
            (o, sink)
        }

        // verifies: UPD-SVC-01
        #[test]
        fn a_signed_image_is_installed_activated_once_and_a_replay_or_another_digest_refused() {
            let img = signed(0x010100, 7);
            let digest = img[mib::update::field::DIGEST..mib::update::field::DIGEST + 32].to_vec();
            let (mut o, _) = booted(slots(img));
            assert_eq!(o.param::<{ pid::SW_VERSION }>(), 0x010000);
            // Nothing installed yet.
            let p = send(&mut o, 10, 1, UPDATE, sub::ACTIVATE, &activate_tc(&digest));
            assert_eq!(failed_with(&p), Some(mib::FailureCode::UPDATE_NOT_INSTALLED.code()));
            let p = send(&mut o, 20, 2, UPDATE, sub::INSTALL, &install_tc(b"new.img"));
            assert_eq!(failed_with(&p), None);
            assert!(events(&p).contains(&eid::UPDATE_INSTALLED));
            assert_eq!(o.param::<{ pid::UPDATE_INSTALLED_VERSION }>(), 0x010100);
            // An activation written for another image.
            let mut other = digest.clone();
            other[31] ^= 1;
            let p = send(&mut o, 30, 3, UPDATE, sub::ACTIVATE, &activate_tc(&other));
            assert_eq!(failed_with(&p), Some(mib::FailureCode::UPDATE_WRONG_IMAGE.code()));
            assert!(!o.update.reset_requested());
            let p = send(&mut o, 40, 4, UPDATE, sub::ACTIVATE, &activate_tc(&digest));
            assert_eq!(failed_with(&p), None);
            assert!(events(&p).contains(&eid::UPDATE_ACTIVATED));
            assert!(o.update.reset_requested());
            // The same activation again (a new TC with the same content).
            let p = send(&mut o, 50, 5, UPDATE, sub::ACTIVATE, &activate_tc(&digest));
            assert_eq!(failed_with(&p), Some(mib::FailureCode::UPDATE_STALE_ACTIVATION.code()));
            assert!(events(&p).contains(&eid::TC_REJECTED));
            assert_eq!(o.param::<{ pid::UPDATE_REFUSALS }>(), 3);
        }

        // verifies: UPD-SVC-02
        #[test]
        fn a_bad_signature_or_truncated_image_is_refused_counted_and_evented() {
            let mut bad = signed(0x010100, 7);
            bad[HEADER_LEN - 1] ^= 0x10;
            let (mut o, _) = booted(slots(bad));
            let p = send(&mut o, 10, 1, UPDATE, sub::INSTALL, &install_tc(b"new.img"));
            assert_eq!(failed_with(&p), Some(mib::FailureCode::UPDATE_IMAGE_REFUSED.code()));
            assert_eq!(failure(&of(&p, 1, 4)[0]).1, [mib::update::refusal::SIGNATURE]);
            assert!(events(&p).contains(&eid::UPDATE_REFUSED));
            let mut short = signed(0x010100, 7);
            short.truncate(short.len() - 100);
            let (mut o, _) = booted(slots(short));
            let p = send(&mut o, 10, 1, UPDATE, sub::INSTALL, &install_tc(b"new.img"));
            assert_eq!(failure(&of(&p, 1, 4)[0]).1, [mib::update::refusal::TRUNCATED]);
            let p = send(&mut o, 20, 2, UPDATE, sub::INSTALL, &install_tc(b"nothere.img"));
            assert_eq!(failure(&of(&p, 1, 4)[0]).1, [mib::update::refusal::NO_FILE]);
            assert_eq!(o.param::<{ pid::UPDATE_REFUSALS }>(), 2);
            assert_eq!(o.param::<{ pid::UPDATE_OUTCOME }>(), i64::from(outcome::REFUSED));
            // Without slots nothing is possible.
            let mut o = obsw();
            let p = send(&mut o, 10, 1, UPDATE, sub::CONFIRM, &[]);
            assert_eq!(failed_with(&p), Some(mib::FailureCode::UPDATE_UNAVAILABLE.code()));
        }

        // verifies: UPD-SVC-03
        #[test]
        fn a_new_image_confirms_after_its_self_test_and_a_failing_one_rolls_back() {
            for fail in [false, true] {
                let s = slots(signed(0x020000, 9));
                let key = s.key().unwrap();
                let img = s.file.clone();
                image::install(&mut &img[..], &mut s.slots[1], &key, target::HOST).unwrap();
                otadata::activate(&mut s.ota, 1).unwrap();
                assert_eq!(otadata::boot(&mut s.ota).unwrap().slot, 1);
                s.fail_self_test = fail;
                // The flash as the reset will find it (a failed self-test writes nothing).
                let after_reset: &'static mut RamSlots = Box::leak(Box::new(s.clone()));
                let (o, p) = booted(s);
                assert_eq!(o.param::<{ pid::SW_VERSION }>(), 0x020000);
                assert_eq!(o.param::<{ pid::SW_SLOT }>(), 1);
                if !fail {
                    assert!(events(&p).contains(&eid::UPDATE_CONFIRMED));
                    assert_eq!(o.param::<{ pid::UPDATE_OUTCOME }>(), i64::from(outcome::CONFIRMED));
                    assert!(!o.update.reset_requested());
                    continue;
                }
                assert!(events(&p).contains(&eid::UPDATE_SELF_TEST_FAILED));
                assert!(o.update.reset_requested());
                // The reset: the boot abandons slot 1, and version 1 reports the rollback.
                let s = after_reset;
                assert_eq!(otadata::boot(&mut s.ota).unwrap().slot, 0);
                s.fail_self_test = false;
                let (o, p) = booted(s);
                assert!(events(&p).contains(&eid::UPDATE_ROLLED_BACK));
                assert_eq!(o.param::<{ pid::SW_VERSION }>(), 0x010000);
                assert_eq!(o.param::<{ pid::UPDATE_OUTCOME }>(), i64::from(outcome::ROLLED_BACK));
            }
        }
    }
}
