//! Defect detection (placeholder on the optim branch; the lead merges the module list).

pub mod search;
