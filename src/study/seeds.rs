//! Hashes behind case keys and seeds (the same on every platform).
//!
//! A case's seed is a function of what the case *is*, never of where it
//! stands in a list: [`super::sweep::expand`] hashes the case's axis
//! columns and values and its repeat number with [`fnv1a`] (the case key)
//! and mixes the key into the study's seed with [`splitmix64`]:
//!
//! ```text
//! key  = fnv1a({"params": [[column, value], ...], "repeat": r} as compact JSON)
//! seed = splitmix64(study.seed ^ key)
//! ```
//!
//! so a study over a subset of an axis's values reproduces the cells of the
//! full study exactly (kinds derive their own seeds from the case seed:
//! kind `fit` uses `seed >> 1` for the data noise and
//! `splitmix64(seed) >> 1` for the search).
//!
//! ```
//! use springmass::study::seeds::{fnv1a, splitmix64};
//! assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
//! assert_ne!(splitmix64(1), splitmix64(2));
//! ```

/// 64-bit FNV-1a: a hash that is the same on every platform and Rust version.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

pub use crate::noise::splitmix64;
