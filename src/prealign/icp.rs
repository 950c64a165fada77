//! Trimmed iterative closest point (Chetverikov et al. 2002) with both directions' matches
//! ([`super::matching`]) and the closed-form Umeyama step ([`super::transform::fit_pairs`]):
//! a rigid motion, or a similarity when the scale is free.

use super::matching::{score_of, Clouds, Level};
use super::transform::{fit_pairs, Similarity};

/// Iterations at most per refinement: on the coarse samples (from a candidate rotation, to its
/// basin), on the full ones (from there, to the score that decides).
pub const MAX_ITERATIONS: [usize; 2] = [40, 10];

/// The refinement stops once an iteration lowers the score by less than this fraction (coarse,
/// full).
pub const TOLERANCE: [f64; 2] = [3e-3, 1e-3];

/// Refines `start` by trimmed ICP on the samples of `level`; returns the best transform seen
/// and its score there.
pub fn refine(clouds: &Clouds, start: Similarity, scaled: bool, level: Level) -> (Similarity, f64) {
    let mut current = start;
    let (mut forward, mut backward) = clouds.matches(&current, level);
    let mut best = (current, score_of(&forward, &backward));
    for _ in 0..MAX_ITERATIONS[level as usize] {
        let pairs: Vec<([f64; 3], [f64; 3])> = forward
            .iter()
            .chain(&backward)
            .map(|&(a, b, _)| (a, b))
            .collect();
        let Some(next) = fit_pairs(&pairs, scaled) else {
            break;
        };
        current = next;
        (forward, backward) = clouds.matches(&current, level);
        let score = score_of(&forward, &backward);
        let improved = score < best.1;
        let converged = score > best.1 * (1.0 - TOLERANCE[level as usize]);
        if improved {
            best = (current, score);
        }
        if converged {
            break;
        }
    }
    best
}
