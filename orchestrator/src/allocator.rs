//! How nlstudy's allocator (mimalloc, set in `main.rs`) gives memory back.
//!
//! mimalloc 3 keeps the pages a collect frees for a second before it returns them to the system
//! (its `purge_delay`, 1000 ms), so the peak resident memory of a collect counts pages already
//! freed: 10⁵ records peaked at 408 MB, 10⁶ at 3.1–3.3 GB. Returned after 100 ms, the same
//! collects peak at 353 MB and 2.8 GB in the same time (docs/performance.md, "The allocator's
//! purge delay"). `MIMALLOC_PURGE_DELAY` in the environment still wins.

use libmimalloc_sys::{mi_option_set_default, mi_option_t};

/// `mi_option_purge_delay` of mimalloc.h, which libmimalloc-sys does not name (its options'
/// numbers are mimalloc's ABI; a test checks this one is the delay by its default).
const PURGE_DELAY: mi_option_t = 15;

/// How long freed pages wait before they are returned to the system, in milliseconds.
const PURGE_AFTER_MS: std::ffi::c_long = 100;

/// Shortens the purge delay unless the environment set it; called first in `main`.
pub fn return_freed_memory_sooner() {
    // SAFETY: options are plain integers, set before any other thread exists (mimalloc's
    // option setters are not thread safe).
    unsafe { mi_option_set_default(PURGE_DELAY, PURGE_AFTER_MS) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use libmimalloc_sys::mi_option_get;

    /// Option 15 is the purge delay: in this process (the tests' allocator is the system's, so
    /// nothing set it) it holds mimalloc 3's default for that option. A mimalloc whose options
    /// moved, or whose default changed, fails here and the setting above is to be measured again.
    #[test]
    fn option_15_is_mimallocs_purge_delay() {
        if std::env::var_os("MIMALLOC_PURGE_DELAY").is_none() {
            // SAFETY: reads an integer option.
            assert_eq!(unsafe { mi_option_get(PURGE_DELAY) }, 1000);
        }
    }
}
