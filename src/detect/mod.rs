//! Defect detection from Laplace-domain data.

pub mod locate;
