//! Defect detection: explicit locators and fitting.

pub mod locate;
pub mod search;
