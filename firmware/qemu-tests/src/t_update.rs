//! Board A's software update on the target: `mmic-update`'s slot logic (signed images,
//! ESP-IDF's otadata, the bootloader's choice and rollback) on RV32IMC over a NOR flash
//! model laid out as board A's flash (`mib::memory`, firmware/partitions.csv): otadata at
//! 0xE000 and the two 576 KiB application slots at 0x10000 and 0xA0000, full size, each
//! reached only through its partition window. The images are the largest the slot's
//! budget allows (`mib::memory::IMAGE_BUDGET`), so the verification costs printed are a
//! worst case. What QEMU cannot show of ESP-IDF's own bootloader is a bring-up item
//! (docs/update.md).

use crate::harness::{Test, TestResult};
use crate::tests;
use crate::{check, check_eq, ok};
use core::cell::RefCell;
use core::ptr::addr_of_mut;
use mib::memory::{FlashRegion, IMAGE_BUDGET, OTADATA, OTA_0, OTA_1};
use mib::update::{target, DIGEST_LEN, HEADER_LEN};
use mmic_update::flash::{Flash, Partition, RamNor};
use mmic_update::image::{self, Header, Refusal, UpdateKey};
use mmic_update::otadata::{self, OtaState};

pub const TESTS: &[Test] = tests![
    update_goes_up_activates_confirms_and_a_broken_one_rolls_back_on_board_a_slots,
    update_bad_signature_truncated_and_unverified_activation_refused_on_board_a_slots,
    update_reset_cut_into_every_otadata_write_leaves_a_bootable_choice_on_board_a_flash,
    update_verification_cost_measured,
];

/// Board A's flash from address 0 to the end of slot 1 (the regions after it play no
/// part): 1.8 MiB of the target's RAM.
const FLASH_END: usize = OTA_1.end() as usize;
type Nor = RamNor<FLASH_END>;
static mut NOR: RefCell<Nor> = RefCell::new(RamNor::new());

/// The largest image the slot's budget allows, header included.
const IMAGE_LEN: usize = IMAGE_BUDGET as usize;
const PAYLOAD_LEN: usize = IMAGE_LEN - HEADER_LEN;
static mut IMAGE: [u8; IMAGE_LEN] = [0; IMAGE_LEN];

/// The ground's update key (a test key; the flight key never leaves the ground).
const SECRET: [u8; 32] = [0x5A; 32];
const A: u8 = target::BOARD_A;

fn v(minor: u32) -> u32 {
    mib::update::version::pack(1, minor, 0).unwrap_or(0)
}

/// The flash model, erased and with power that never fails (each test starts so).
fn nor() -> &'static RefCell<Nor> {
    // SAFETY: one hart, tests run one after another, and each takes the flash once.
    let n = unsafe { &*addr_of_mut!(NOR) };
    let mut f = n.borrow_mut();
    f.bytes.fill(0xFF);
    f.cut_after(None);
    drop(f);
    n
}

/// An image signed by the ground's key: `version` over a payload of its own (the version
/// seeds it, so two versions differ in every block).
fn image_of(version: u32) -> Option<&'static mut [u8; IMAGE_LEN]> {
    // SAFETY: as `nor`: one user at a time.
    let img = unsafe { &mut *addr_of_mut!(IMAGE) };
    let mut x = version | 1;
    for b in img[HEADER_LEN..].iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *b = x as u8;
    }
    let h = image::sign(&SECRET, version, A, &img[HEADER_LEN..])?;
    img[..HEADER_LEN].copy_from_slice(&h);
    Some(img)
}

fn key() -> Option<UpdateKey> {
    UpdateKey::from_bytes(&image::public_key(&SECRET))
}

/// A region of the flash as its partition.
fn part(nor: &RefCell<Nor>, r: FlashRegion) -> Option<Partition<'_, Nor>> {
    Partition::new(nor, r.offset, r.size)
}

/// Board A's three update partitions over the one flash.
struct Board {
    nor: &'static RefCell<Nor>,
}

impl Board {
    fn new() -> Option<Self> {
        let nor = nor();
        part(nor, OTADATA)?;
        part(nor, OTA_0)?;
        part(nor, OTA_1)?;
        Some(Board { nor })
    }
    fn otadata(&self) -> Partition<'static, Nor> {
        // The MIB's regions lie inside the model, sector aligned (checked by `new`).
        part(self.nor, OTADATA).unwrap_or_else(|| unreachable!())
    }
    fn slot(&self, n: u8) -> Partition<'static, Nor> {
        part(self.nor, if n == 0 { OTA_0 } else { OTA_1 }).unwrap_or_else(|| unreachable!())
    }
    /// Installs `img` into slot `n` (copied, then verified from what the slot holds).
    fn install(&self, img: &[u8], n: u8, key: &UpdateKey) -> Result<Header, Refusal> {
        image::install(&mut &img[..], &mut self.slot(n), key, A)
    }
    /// Activates slot `n` if it holds, verified now, the image `digest` names.
    fn activate(&self, n: u8, key: &UpdateKey, digest: &[u8; DIGEST_LEN]) -> Result<Header, Refusal> {
        image::activate_verified(&mut self.otadata(), &mut self.slot(n), n, key, A, digest)
    }
    /// A reset: ESP-IDF's second-stage bootloader's choice (with rollback), then the image
    /// it starts verifies its own slot — the self-test's first check — and confirms itself
    /// when `healthy` (a broken image never gets there).
    fn reset(&self, key: &UpdateKey, healthy: bool) -> Result<(otadata::Boot, Header), Refusal> {
        let b = otadata::boot(&mut self.otadata()).map_err(|_| Refusal::Flash)?;
        let h = image::verify_slot(&mut self.slot(b.slot), key, A)?;
        if healthy && b.state == Some(OtaState::PendingVerify) {
            otadata::confirm(&mut self.otadata()).map_err(|_| Refusal::Flash)?;
        }
        Ok((b, h))
    }
    fn otadata_bytes(&self) -> [u8; OTADATA.size as usize] {
        let mut b = [0; OTADATA.size as usize];
        let _ = self.otadata().read(0, &mut b);
        b
    }
    /// Power fails after `steps` more byte programs or sector erases (`None`: never).
    fn cut_after(&self, steps: Option<usize>) {
        self.nor.borrow_mut().cut_after(steps);
    }
}

/// v1 in slot 0 from the factory (otadata erased: slot 0 boots); v2 goes up into slot 1,
/// is verified, activated, boots PENDING_VERIFY, confirms, and stays after another reset;
/// v3 goes up into slot 0 and never confirms: the next boot aborts it and v2 runs again,
/// told it was rolled back to, and stays.
// verifies: UPD-QEMU-01, UPD-OTA-02
fn update_goes_up_activates_confirms_and_a_broken_one_rolls_back_on_board_a_slots() -> TestResult {
    let k = ok!(key());
    let board = ok!(Board::new());
    let v1 = ok!(board.install(ok!(image_of(v(1))), 0, &k));
    let (b, h) = ok!(board.reset(&k, true));
    check_eq!((b.slot, b.state, h.version), (0, None, v(1)), "factory boot");

    let v2 = ok!(board.install(ok!(image_of(v(2))), 1, &k));
    check_eq!(v2.length as usize, PAYLOAD_LEN);
    check_eq!(ok!(board.activate(1, &k, &v2.digest)).version, v(2));
    let (b, h) = ok!(board.reset(&k, true));
    check_eq!((b.slot, b.state, h.version), (1, Some(OtaState::PendingVerify), v(2)));
    let (b, h) = ok!(board.reset(&k, true));
    check_eq!(
        (b.slot, b.state, h.version),
        (1, Some(OtaState::Valid), v(2)),
        "confirmed v2 stays"
    );

    let v3 = ok!(board.install(ok!(image_of(v(3))), 0, &k));
    check!(v3.digest != v1.digest);
    ok!(board.activate(0, &k, &v3.digest));
    let (b, h) = ok!(board.reset(&k, false));
    check_eq!((b.slot, b.state, h.version), (0, Some(OtaState::PendingVerify), v(3)));
    let (b, h) = ok!(board.reset(&k, true));
    check_eq!(
        (b.slot, b.state, b.aborted),
        (1, Some(OtaState::Valid), Some(0)),
        "rolled back"
    );
    check_eq!(h.version, v(2));
    let run = ok!(otadata::running(&mut board.otadata()));
    check_eq!((run.slot, run.rolled_back_from), (1, Some(0)));
    let (b, h) = ok!(board.reset(&k, true));
    check_eq!((b.slot, b.aborted, h.version), (1, None, v(2)), "and v2 stays");
    Ok(())
}

/// With v2 running confirmed in slot 1 and v3 verified in slot 0: an image with one
/// signature bit changed and one a byte short are refused before anything is written (the
/// slot still holds v3, the otadata is untouched); an activation naming another image
/// (the running v2's digest, a replayed activation), of a slot changed after its
/// verification, and of an erased slot are refused with the otadata untouched; v2 still
/// boots.
// verifies: UPD-QEMU-01, UPD-IMG-02
fn update_bad_signature_truncated_and_unverified_activation_refused_on_board_a_slots() -> TestResult {
    let k = ok!(key());
    let board = ok!(Board::new());
    ok!(board.install(ok!(image_of(v(1))), 0, &k));
    let v2 = ok!(board.install(ok!(image_of(v(2))), 1, &k));
    ok!(board.activate(1, &k, &v2.digest));
    ok!(board.reset(&k, true));
    let v3 = ok!(board.install(ok!(image_of(v(3))), 0, &k));
    let ota = board.otadata_bytes();

    let img = ok!(image_of(v(4)));
    img[HEADER_LEN - 1] ^= 0x01;
    check_eq!(board.install(img, 0, &k), Err(Refusal::Signature));
    img[HEADER_LEN - 1] ^= 0x01;
    check_eq!(
        ok!(image::verify_slot(&mut board.slot(0), &k, A)),
        v3,
        "slot 0 untouched"
    );
    let short = &img[..IMAGE_LEN - 1];
    check!(matches!(board.install(short, 0, &k), Err(Refusal::Truncated { .. })));
    check_eq!(
        ok!(image::verify_slot(&mut board.slot(0), &k, A)),
        v3,
        "slot 0 untouched"
    );
    check!(board.otadata_bytes() == ota, "no refusal wrote otadata");

    // Activations of what is not the verified image named.
    check_eq!(
        board.activate(0, &k, &v2.digest),
        Err(Refusal::Digest),
        "replayed v2 activation"
    );
    // One payload bit cleared after the verification (a NOR write only clears bits).
    let mut at = HEADER_LEN as u32 + 4096;
    let mut byte = [0u8];
    loop {
        ok!(board.slot(0).read(at, &mut byte));
        if byte[0] != 0 {
            break;
        }
        at += 1;
    }
    ok!(board.slot(0).write(at, &[byte[0] & (byte[0] - 1)]));
    check_eq!(
        board.activate(0, &k, &v3.digest),
        Err(Refusal::Digest),
        "slot changed after verification"
    );
    ok!(board.slot(0).erase(0, OTA_0.size));
    check_eq!(
        board.activate(0, &k, &v3.digest),
        Err(Refusal::NotAnImage),
        "erased slot"
    );
    check!(board.otadata_bytes() == ota, "no refused activation wrote otadata");
    let (b, h) = ok!(board.reset(&k, true));
    check_eq!((b.slot, h.version), (1, v(2)));
    Ok(())
}

/// The power cut after every byte program and sector erase of the activation, of the
/// bootloader's NEW → PENDING_VERIFY and PENDING_VERIFY → ABORTED and of the confirmation,
/// on board A's otadata: each cut boots the image that ran (and keeps it) or the one
/// activated, unconfirmed (and the next boot returns to the one that ran); the slots are
/// never touched.
// verifies: UPD-QEMU-01, UPD-OTA-03
fn update_reset_cut_into_every_otadata_write_leaves_a_bootable_choice_on_board_a_flash() -> TestResult {
    let k = ok!(key());
    let board = ok!(Board::new());
    let v1 = ok!(board.install(ok!(image_of(v(1))), 0, &k));
    let v2 = ok!(board.install(ok!(image_of(v(2))), 1, &k));
    // An earlier update left v2 running confirmed in slot 1 (its record in sector 0); v1,
    // verified in slot 0, is activated again (a recovery): its record goes to sector 1.
    ok!(board.activate(1, &k, &v2.digest));
    ok!(board.reset(&k, true));
    let ran = board.otadata_bytes();
    ok!(otadata::activate(&mut board.otadata(), 0));
    let activated = board.otadata_bytes();
    ok!(otadata::boot(&mut board.otadata()));
    let pending = board.otadata_bytes();

    type Op = fn(&Board) -> bool;
    let ops: [(&str, &[u8; OTADATA.size as usize], Op); 4] = [
        ("activate", &ran, |b| otadata::activate(&mut b.otadata(), 0).is_ok()),
        ("mark pending", &activated, |b| otadata::boot(&mut b.otadata()).is_ok()),
        ("confirm", &pending, |b| otadata::confirm(&mut b.otadata()).is_ok()),
        ("abort", &pending, |b| otadata::boot(&mut b.otadata()).is_ok()),
    ];
    // (cuts that boot v2 as it ran, cuts that boot v1 unconfirmed and roll back after)
    let (mut kept, mut new) = (0, 0);
    for (name, start, op) in ops {
        let mut cuts = 0;
        for steps in 0.. {
            ok!(board.otadata().erase(0, OTADATA.size));
            ok!(board.otadata().write(0, start));
            board.cut_after(Some(steps));
            let done = op(&board);
            board.cut_after(None);
            if done {
                break;
            }
            cuts += 1;
            // The first boot starts v2 as it ran (slot 1, confirmed) or v1 as activated
            // (slot 0, unconfirmed); after v1 unconfirmed the second boot aborts it for v2,
            // after v2 it keeps v2.
            let b1 = ok!(otadata::boot(&mut board.otadata()));
            let b2 = ok!(otadata::boot(&mut board.otadata()));
            let v2_again = (b2.slot, b2.state) == (1, Some(OtaState::Valid));
            match (b1.slot, b1.state) {
                (1, Some(OtaState::Valid)) if v2_again && b2.aborted.is_none() => kept += 1,
                (0, Some(OtaState::PendingVerify)) if name != "abort" && v2_again && b2.aborted == Some(0) => new += 1,
                _ => check!(false, "{} cut after {}: {:?} then {:?}", name, steps, b1, b2),
            }
        }
        check!(
            cuts >= 33,
            "{}: an erase and 32 byte writes at least were cut ({})",
            name,
            cuts
        );
    }
    check_eq!(
        ok!(image::verify_slot(&mut board.slot(0), &k, A)),
        v1,
        "slot 0 never touched"
    );
    check_eq!(
        ok!(image::verify_slot(&mut board.slot(1), &k, A)),
        v2,
        "slot 1 never touched"
    );
    semihosting::println!(
        "    {} power cuts into board A's otadata writes (activate, mark pending, confirm, abort): {} boot v2 as it ran, {} v1 unconfirmed then v2 again; none another",
        kept + new,
        kept,
        new
    );
    Ok(())
}

fn instret() -> u64 {
    riscv::register::minstret::read64()
}

/// What a verification costs on RV32IMC: the Ed25519 check of the header's signature and
/// the SHA-256 of the largest image the slot's budget allows, read from the slot, against
/// the control period's instruction budget.
// verifies: UPD-QEMU-01
fn update_verification_cost_measured() -> TestResult {
    use mib::config::{PERIOD_INSTRUCTIONS, PERIOD_INSTRUCTION_BUDGET};
    let k = ok!(key());
    let board = ok!(Board::new());
    let h = ok!(board.install(ok!(image_of(v(2))), 1, &k));
    let mut slot = board.slot(1);
    let mut sig = [0u64; 3];
    let mut whole = [0u64; 3];
    for (s, w) in sig.iter_mut().zip(whole.iter_mut()) {
        let t = instret();
        let r = h.check_signature(&k);
        *s = instret() - t;
        check_eq!(r, Ok(()));
        let t = instret();
        let r = image::verify_slot(&mut slot, &k, A);
        *w = instret() - t;
        check_eq!(r, Ok(h));
    }
    sig.sort_unstable();
    whole.sort_unstable();
    let (ed, all) = (sig[1], whole[1]);
    let digest = all.saturating_sub(ed);
    let per_kib = digest * 1024 / PAYLOAD_LEN as u64;
    let budget = PERIOD_INSTRUCTION_BUDGET as u64;
    semihosting::println!(
        "    verify (median of 3) of a {}-byte image (the slot's budget): {} instructions = Ed25519 {} + SHA-256 and slot reads {} ({} per KiB); a period holds {}, its budget {}: Ed25519 alone {:.1} budgets, the whole verification {:.1}",
        IMAGE_LEN,
        all,
        ed,
        digest,
        per_kib,
        PERIOD_INSTRUCTIONS,
        budget,
        ed as f64 / budget as f64,
        all as f64 / budget as f64
    );
    check!(ed > 0 && digest > 0);
    Ok(())
}
