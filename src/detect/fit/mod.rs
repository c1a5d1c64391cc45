//! Fitting defects to observations.

pub mod chainfit;
pub mod general;
pub mod identify;
pub mod paper;
pub mod select;
