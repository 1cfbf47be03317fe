//! A minimal test runner for bare metal: each test returns `Result<(), Failure>`; the
//! `check!` macros return early with the file, line and a message instead of panicking,
//! so one failing test does not stop the others. A panic still ends the run (no
//! unwinding on this target) and is reported as a failure of the running test.

use core::fmt::Write;
use core::sync::atomic::{AtomicUsize, Ordering};

pub struct Failure {
    pub file: &'static str,
    pub line: u32,
    pub msg: heapless::String<192>,
}

impl Failure {
    pub fn new(file: &'static str, line: u32, args: core::fmt::Arguments<'_>) -> Self {
        let mut msg = heapless::String::new();
        // A message longer than the buffer is cut; the location identifies the check.
        let _ = msg.write_fmt(args);
        Failure { file, line, msg }
    }
}

pub type TestResult = Result<(), Failure>;

pub struct Test {
    pub name: &'static str,
    pub run: fn() -> TestResult,
}

/// `check!(cond)` or `check!(cond, "format", args..)`.
#[macro_export]
macro_rules! check {
    ($cond:expr) => {
        if !$cond {
            return Err($crate::harness::Failure::new(
                file!(),
                line!(),
                format_args!("check failed: {}", stringify!($cond)),
            ));
        }
    };
    ($cond:expr, $($arg:tt)+) => {
        if !$cond {
            return Err($crate::harness::Failure::new(file!(), line!(), format_args!($($arg)+)));
        }
    };
}

/// `check_eq!(left, right)`: both sides must be `PartialEq + Debug`.
#[macro_export]
macro_rules! check_eq {
    ($left:expr, $right:expr $(,)?) => {
        match (&$left, &$right) {
            (l, r) => {
                if !(*l == *r) {
                    return Err($crate::harness::Failure::new(
                        file!(),
                        line!(),
                        format_args!(
                            "{} == {}: left {:?}, right {:?}",
                            stringify!($left),
                            stringify!($right),
                            l,
                            r
                        ),
                    ));
                }
            }
        }
    };
    ($left:expr, $right:expr, $($arg:tt)+) => {
        match (&$left, &$right) {
            (l, r) => {
                if !(*l == *r) {
                    let mut m: heapless::String<96> = heapless::String::new();
                    let _ = core::fmt::Write::write_fmt(&mut m, format_args!($($arg)+));
                    return Err($crate::harness::Failure::new(
                        file!(),
                        line!(),
                        format_args!("{}: left {:?}, right {:?}", m, l, r),
                    ));
                }
            }
        }
    };
}

/// `Ok(v)` of a `Result`/`Some(v)` of an `Option`, or a failure naming the expression.
#[macro_export]
macro_rules! ok {
    ($e:expr) => {
        match $crate::harness::IntoCheck::into_check($e) {
            Some(v) => v,
            None => {
                return Err($crate::harness::Failure::new(
                    file!(),
                    line!(),
                    format_args!("{} gave no value", stringify!($e)),
                ))
            }
        }
    };
}

pub trait IntoCheck<T> {
    fn into_check(self) -> Option<T>;
}
impl<T> IntoCheck<T> for Option<T> {
    fn into_check(self) -> Option<T> {
        self
    }
}
impl<T, E> IntoCheck<T> for Result<T, E> {
    fn into_check(self) -> Option<T> {
        self.ok()
    }
}

static CURRENT: AtomicUsize = AtomicUsize::new(usize::MAX);
static PASSED: AtomicUsize = AtomicUsize::new(0);
static FAILED: AtomicUsize = AtomicUsize::new(0);

/// Runs every test, prints one line per test and the summary; returns the exit code.
pub fn run(groups: &[&[Test]]) -> i32 {
    let total: usize = groups.iter().map(|g| g.len()).sum();
    semihosting::println!("running {} tests on riscv32imc (qemu virt)", total);
    let mut index = 0;
    for group in groups {
        for t in group.iter() {
            CURRENT.store(index, Ordering::Relaxed);
            match (t.run)() {
                Ok(()) => {
                    PASSED.store(PASSED.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
                    semihosting::println!("test {} ... ok", t.name);
                }
                Err(f) => {
                    FAILED.store(FAILED.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
                    semihosting::println!("test {} ... FAILED", t.name);
                    semihosting::println!("    {}:{}: {}", f.file, f.line, f.msg.as_str());
                }
            }
            index += 1;
        }
    }
    CURRENT.store(usize::MAX, Ordering::Relaxed);
    let passed = PASSED.load(Ordering::Relaxed);
    let failed = FAILED.load(Ordering::Relaxed);
    semihosting::println!();
    semihosting::println!("{} passed, {} failed", passed, failed);
    if failed == 0 && passed == total {
        0
    } else {
        1
    }
}

/// Called by the panic handler: the running test failed and the run ends here.
pub fn report_panic(info: &core::panic::PanicInfo<'_>) {
    let passed = PASSED.load(Ordering::Relaxed);
    let failed = FAILED.load(Ordering::Relaxed) + 1;
    let cur = CURRENT.load(Ordering::Relaxed);
    semihosting::println!("test #{} ... PANICKED: {}", cur + 1, info);
    semihosting::println!();
    semihosting::println!("{} passed, {} failed", passed, failed);
}

/// `tests![a, b, c]`: a table of test functions named after themselves.
#[macro_export]
macro_rules! tests {
    ($($f:ident),* $(,)?) => {
        &[$($crate::harness::Test { name: stringify!($f), run: $f }),*]
    };
}

/// The worst `Obsw::tick` of `t_obsw`'s run, for the control-period budget (`t_budget`).
pub static WORST_TICK: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);
/// The worst `Obsw::handle_tc` of `t_obsw`'s run (`t_budget`).
pub static WORST_TC: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);
/// The most TM packets one `Obsw::tick` of `t_obsw`'s run sent (`t_budget`).
pub static MOST_TICK_PACKETS: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);
/// The most TM packets one `Obsw::handle_tc` of `t_obsw` sent (framed on the board).
pub static MOST_TC_PACKETS: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);
/// What a period's store writes into board A's flash store take beyond the RAM ring the
/// tick was measured with (`t_store`).
pub static STORE_WRITES_EXTRA: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);

/// The most instructions a paced PUS 15 replay from a full flash store read in one period
/// (`t_store`: the store's reading and the replay's filter, not the framing of what it sent).
pub static REPLAY_READ_WORST: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);
/// The most packets that replay sent in one period (framed on the board, `t_budget`).
pub static REPLAY_MOST_SENT: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);

/// The most instructions board A's file service took in a period that took a file data
/// packet of a whole segment (`t_files`: the packet and the service's poll), in place of
/// the period's TC packet (`t_budget`).
pub static WORST_FILE_DATA: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);

/// The most instructions board A's file service took in a period of `t_files`' puts (file
/// data written, the received file's paced checksum), of its get (a segment read and sent,
/// the sent file's sum, the request taken) or in one that handled an EOF, in place of the
/// period's TC packet (`t_budget`, enforced).
pub static WORST_FILE_PERIOD: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);

/// The most instructions the file service's poll took in a period that handled a packet
/// (it reads nothing of the store then): what it adds to a period's TC (`t_budget`).
pub static WORST_FILE_QUIET_POLL: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);

/// Instructions of a file's modular checksum per KiB read from the RAM store (`t_files`):
/// the entity sums `mib::cfdp::CHECKSUM_BYTES_PER_POLL` of a file a period.
pub static CHECKSUM_PER_KIB: portable_atomic::AtomicU64 = portable_atomic::AtomicU64::new(0);

/// Bytes below the caller's frame that [`stack_depth`] paints.
pub const STACK_PROBE_BYTES: usize = 96 * 1024;
/// Word painted below the stack pointer (`mib::memory::STACK_PAINT` in every byte).
const PAINT: u32 = u32::from_ne_bytes([mib::memory::STACK_PAINT; 4]);
/// Words just below the caller's frame left unpainted: `paint`'s own frame lives there.
const PAINT_GAP: usize = 256;

/// Runs `f` and returns how deep it used the stack below this function's frame, in
/// bytes: the stack is painted for [`STACK_PROBE_BYTES`] below the stack pointer, `f`
/// runs, and the lowest word no longer holding the paint is its high-water mark (the
/// method the images use at start-up, over their whole stack).
#[inline(never)]
pub fn stack_depth<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let sp: usize;
    // SAFETY: reads the stack pointer register.
    unsafe { core::arch::asm!("mv {}, sp", out(reg) sp) };
    let low = sp - STACK_PROBE_BYTES;
    paint(low, sp - PAINT_GAP);
    let r = f();
    let mut a = low;
    // SAFETY: [low, sp − PAINT_GAP) is this stack's free space below the current frame
    // (QEMU's RAM holds the stack far deeper than the probe), read word by word.
    while a < sp - PAINT_GAP && unsafe { core::ptr::read_volatile(a as *const u32) } == PAINT {
        a += 4;
    }
    (r, sp - a)
}

#[inline(never)]
fn paint(from: usize, to: usize) {
    let mut a = from;
    while a < to {
        // SAFETY: free stack below the caller's frame and above `paint`'s own (PAINT_GAP).
        unsafe { core::ptr::write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
}
