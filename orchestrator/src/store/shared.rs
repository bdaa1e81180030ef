//! Texts shared by the many values that repeat them.

use std::cell::RefCell;
use std::collections::HashSet;
use std::sync::Arc;

/// A text many values repeat (a column's name, a solver's fingerprint or version, a segment's
/// name), made once and shared: at 10⁶ records a copy each is millions of allocations.
pub type Shared = Arc<str>;

/// How many distinct texts a thread keeps for sharing: more than a table has columns or a
/// store has builds and segments.
const SHARED_KEPT: usize = 4096;

/// `text` as a `Shared`: the one this thread made before, if any.
pub fn shared(text: &str) -> Shared {
    thread_local! {
        // (foldhash: a collect asks for a name at every cell of every row.)
        static KEPT: RefCell<HashSet<Shared, foldhash::fast::RandomState>> = Default::default();
    }
    KEPT.with_borrow_mut(|kept| match kept.get(text) {
        Some(shared) => shared.clone(),
        None => {
            let shared: Shared = text.into();
            if kept.len() < SHARED_KEPT {
                kept.insert(shared.clone());
            }
            shared
        }
    })
}
