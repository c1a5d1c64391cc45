//! The thread policy of the searches and fits: where a map over items goes
//! to rayon's pool and where it stays on the calling thread.
//!
//! * **Only large work is shared.** A map goes to the pool when it is asked
//!   for (the options' `parallel`), holds at least its site's minimum of
//!   items and the pool has more than one thread. A fit decides once per
//!   number of defects whether it is large ([`MIN_SETS`] position sets or
//!   more): a small fit (Table 1's n = 20, k = 2: 190 sets) runs on one
//!   thread, since waking idle workers for a few milliseconds of work costs
//!   more CPU than it saves.
//! * **Never nested.** Every task of a parallel map ([`map`]) and every
//!   case of a study ([`as_task`]) runs marked as a task; a map asked for
//!   inside a task runs sequentially. A study running its cases in
//!   parallel thus runs each fit on one thread.
//! * **The thread count is the pool's**: `RAYON_NUM_THREADS` or the
//!   caller's pool (`ThreadPool::install`, as the study's `--threads` and
//!   the command line's `--threads` do).
//!
//! Results never depend on the thread count: maps return their outputs in
//! the order of their items, and every reduction is made after the map,
//! in that order.

use rayon::prelude::*;
use std::cell::Cell;

thread_local! {
    /// Whether this thread is running a task of a parallel map or a study case.
    static IN_TASK: Cell<bool> = const { Cell::new(false) };
}

/// Position (and kind) sets of one number of defects from which a fit
/// shares its work among threads.
pub const MIN_SETS: usize = 2000;

/// Whether a map of `items` items (at least `min_items` for its site) goes
/// to the pool: asked for, large enough, more than one thread, and not
/// inside a task of another map.
pub fn worth(parallel: bool, items: usize, min_items: usize) -> bool {
    parallel
        && items >= min_items.max(2)
        && rayon::current_num_threads() > 1
        && !IN_TASK.with(Cell::get)
}

/// Whether the calling thread runs a task of a parallel map or a study case.
pub fn in_task() -> bool {
    IN_TASK.with(Cell::get)
}

/// `f()` marked as a task: maps inside it run on this thread.
pub fn as_task<R>(f: impl FnOnce() -> R) -> R {
    let before = IN_TASK.with(|c| c.replace(true));
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            IN_TASK.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(before);
    f()
}

/// `f` over `items`, on the pool when [`worth`] it (each item a task),
/// else in order on this thread; the outputs in the order of `items`.
pub fn map<T: Sync, U: Send>(
    items: &[T],
    parallel: bool,
    min_items: usize,
    f: impl Fn(&T) -> U + Sync + Send,
) -> Vec<U> {
    if worth(parallel, items.len(), min_items) {
        items.par_iter().map(|x| as_task(|| f(x))).collect()
    } else {
        items.iter().map(f).collect()
    }
}

/// [`map`] with a per-thread scratch value made by `init`.
pub fn map_init<T: Sync, U: Send, S>(
    items: &[T],
    parallel: bool,
    min_items: usize,
    init: impl Fn() -> S + Sync + Send,
    f: impl Fn(&mut S, &T) -> U + Sync + Send,
) -> Vec<U> {
    if worth(parallel, items.len(), min_items) {
        items
            .par_iter()
            .map_init(init, |s, x| as_task(|| f(s, x)))
            .collect()
    } else {
        let mut s = init();
        items.iter().map(|x| f(&mut s, x)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_keep_order_and_do_not_nest() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let items: Vec<usize> = (0..64).collect();
        let (out, inner) = pool.install(|| {
            let out = map(&items, true, 2, |&i| (i * i, worth(true, 100, 2)));
            (out, worth(true, 100, 2))
        });
        assert!(inner, "the pool's own thread may share work");
        for (i, (sq, nested)) in out.into_iter().enumerate() {
            assert_eq!(sq, i * i);
            assert!(!nested, "a map inside a task runs sequentially");
        }
        assert!(!worth(true, 1, 1), "one item is never shared");
        assert!(!worth(false, 100, 2));
        assert!(as_task(|| !worth(true, 100, 2)));
        assert!(!in_task(), "the mark is restored");
    }
}
