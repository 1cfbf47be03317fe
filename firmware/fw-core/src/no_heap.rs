//! No heap, said to the linker: a global allocator with no memory. cfdp-rs (under the CFDP
//! entity, `crate::files`) links the `alloc` crate through `smallvec`, whose spill to the
//! heap the entity never reaches (it hands cfdp-rs metadata without messages to user, the
//! only list kept in one, of at most 16 inline), and a binary that links `alloc` must
//! name an allocator. Every allocation from this one fails: `alloc::alloc::handle_alloc_error`
//! panics (on board A: the panic record, PREVIOUS_PANIC after the reset), so an allocation
//! cannot pass unseen. The images and the QEMU binaries install it:
//!
//! ```ignore
//! #[global_allocator]
//! static NO_HEAP: fw_core::no_heap::NoHeap = fw_core::no_heap::NoHeap;
//! ```

use core::alloc::{GlobalAlloc, Layout};

/// The allocator without memory (see the module documentation).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoHeap;

// SAFETY: `alloc` returns null, which `GlobalAlloc` defines as the allocation's failure;
// `dealloc` is then never called with a pointer of ours.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for NoHeap {
    unsafe fn alloc(&self, _layout: Layout) -> *mut u8 {
        core::ptr::null_mut()
    }
    unsafe fn dealloc(&self, _ptr: *mut u8, _layout: Layout) {}
}
