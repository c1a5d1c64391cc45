//! The report's check for hidden defects (made by
//! [`crate::detect::fit::unseen`]): the elements whose halving or doubling
//! the data would not show.

use crate::detect::unknowns::DefectKind;
use serde::Serialize;

/// Standard errors a change must span to count as seen: it must move
/// `chi^2` by at least `Z^2 = 4` (the report's visibility line uses the same
/// two standard errors).
pub const Z: f64 = 2.0;

/// One element whose halving or doubling the data would not show.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct UnseenElement {
    /// `mass` or `spring`.
    pub kind: &'static str,
    /// Its position (a mass `1..=n`, a spring `0..=n`).
    pub at: usize,
}

/// The check's result: the elements whose halving or doubling the data
/// would not show (the report's JSON field `unseen`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Unseen {
    /// Each such element, masses first, by position.
    pub elements: Vec<UnseenElement>,
    /// The elements probed.
    pub checked: usize,
    /// The elements the answer leaves unchanged (more than `checked` on a
    /// chain longer than [`crate::detect::fit::unseen::MAX_PROBES`]).
    pub of: usize,
}

impl Unseen {
    /// One line for the report's message.
    pub fn line(&self) -> String {
        let mut parts = Vec::new();
        for kind in DefectKind::ALL {
            let at: Vec<usize> = self
                .elements
                .iter()
                .filter(|e| e.kind == kind.name())
                .map(|e| e.at)
                .collect();
            if !at.is_empty() {
                parts.push(format!("{} {}", kind.name(), ranges(&at)));
            }
        }
        let sampled = if self.checked < self.of {
            format!(" ({} of {} elements probed)", self.checked, self.of)
        } else {
            String::new()
        };
        format!(
            "the data would not show a further defect halving or doubling {}{sampled} (less than {Z} standard errors): the answer is the best fit, but the record does not rule out more defects there",
            parts.join(", ")
        )
    }
}

/// `1-3, 7, 9-12`.
pub(crate) fn ranges(at: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < at.len() {
        let mut j = i;
        while j + 1 < at.len() && at[j + 1] == at[j] + 1 {
            j += 1;
        }
        out.push(if j > i {
            format!("{}-{}", at[i], at[j])
        } else {
            at[i].to_string()
        });
        i = j + 1;
    }
    out.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_join_runs() {
        assert_eq!(ranges(&[1, 2, 3, 7, 9, 10]), "1-3, 7, 9-10");
        assert_eq!(ranges(&[4]), "4");
    }
}
