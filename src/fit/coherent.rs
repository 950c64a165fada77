//! The coherent candidate (docs/method.md "Coherent candidate"): a fit of a scan of the
//! garment alone that ended far from its rest shape — its edges spread by at least
//! [`Schedule::coherent_gate`](super::Schedule::coherent_gate), the verdict's
//! `edge_distortion` — is fitted a second time. The template, where the first fit started, is
//! moved onto the scan by non-rigid Coherent Point Drift (Myronenko & Song 2010,
//! [`crate::cpd`]): one smooth motion field over the whole garment, which places a drape, a
//! heap or a flag as a whole instead of letting each region lock onto the nearest surface. The
//! fit from there, with the moved shape as its rest shape (its metric is the one the drape
//! needs), is kept when it lies closer to the scan than the first fit in both directed
//! distances, their sum by [`COHERENT_MARGIN`]; its verdict is measured against the template as
//! given, as the first fit's.

use super::placement::PlacedFit;
use super::{kept_points, CoherentFigures, FitResult, Method, Progress};
use crate::cpd::{coherent_point_drift, CpdParams};
use crate::error::Result;

/// The candidate replaces the first fit only when it lies closer to the scan in both directed
/// distances and their sum is smaller by this share, as another reading replaces the first
/// ([`READING_MARGIN`](super::READING_MARGIN)): where it gains less, the two fits tie by
/// what the scan says, and the first keeps the template's own metric (on the harness the kept
/// candidates gain 5.5–13 %, the folded T-shirts' tie at 1.1–1.4 %;
/// docs/notes/coherent-candidate.md).
pub const COHERENT_MARGIN: f64 = 0.04;

/// The most [`unsupported_share`](crate::quality::Quality::unsupported_share) of a first fit
/// that gets a candidate: Coherent Point Drift models the scan as a sample of the whole
/// template (its outlier term absorbs clutter, not missing parts), so on a scan that saw part
/// of the garment its motion draws the unseen side onto the seen one. The harness's whole scans
/// that reach the gate leave 0.4–2.4 % of their vertices without support, its front-only scans
/// 13–15 % (docs/notes/coherent-candidate.md).
pub const COHERENT_MAX_UNSUPPORTED: f64 = 0.05;

/// The first fit, as its candidate fits the template again (in the user's frame).
pub(super) struct Candidate<'p, 'a> {
    /// Whether the fit's inputs allow a candidate: no landmarks, no rest shape of its own (not
    /// a tracked frame), not a garment pass or one garment of several.
    pub eligible: bool,
    /// The first fit's scan, rest shape, role and parameters.
    pub fit: &'p PlacedFit<'a>,
    /// The scan points of positive weight (`None`: all).
    pub kept: Option<&'a [usize]>,
}

impl Candidate<'_, '_> {
    /// Whether `first`, a finished fit of the FoldMatch method, gets a candidate: its inputs are
    /// eligible, it fitted a scan of the garment alone (not one set for garment passes),
    /// spread its edges past the gate and found scan support for all but
    /// [`COHERENT_MAX_UNSUPPORTED`] of its vertices.
    pub(super) fn gated(&self, first: &FitResult) -> bool {
        let params = self.fit.params;
        let gate = params.schedule.coherent_gate;
        self.eligible
            && gate > 0.0
            && params.method == Method::FoldMatch
            && !first.diagnostics.dressed
            && !first.diagnostics.stopped_by_callback
            && !first.diagnostics.kept_start
            && first.quality.edge_distortion >= gate
            && first.quality.unsupported_share <= COHERENT_MAX_UNSUPPORTED
    }

    /// `first` (fitted from `start`, the placed template, which is its rest shape), or, when it
    /// is [`gated`](Self::gated), the coherent candidate if that lies closer to the scan in both
    /// directed distances, their sum by [`COHERENT_MARGIN`]; either with [`CoherentFigures`] in its
    /// diagnostics when the candidate ran. The candidate's fit reports its progress to `observer`
    /// as a fit of its own (from iteration 1 again); when the observer stops it, `first` is
    /// returned, marked stopped.
    pub(super) fn after(
        &self,
        mut first: FitResult,
        start: &[[f64; 3]],
        observer: &mut (dyn FnMut(&Progress) -> bool + Send),
    ) -> Result<FitResult> {
        if !self.gated(&first) {
            return Ok(first);
        }
        let clock = std::time::Instant::now();
        let scan = kept_points(self.fit.target, self.kept);
        let cpd = coherent_point_drift(start, &scan, &CpdParams::default());
        let mut second = self.fit.fit(&cpd.points, Some(start), observer)?;
        let stopped = second.diagnostics.stopped_by_callback;
        let (a, b) = (&first.quality, &second.quality);
        let kept = !stopped
            && b.fit_to_scan < a.fit_to_scan
            && b.scan_to_fit < a.scan_to_fit
            && b.fit_to_scan + b.scan_to_fit
                < (1.0 - COHERENT_MARGIN) * (a.fit_to_scan + a.scan_to_fit);
        let figures = CoherentFigures {
            edge_distortion: a.edge_distortion,
            fit_to_scan: [a.fit_to_scan, b.fit_to_scan],
            scan_to_fit: [a.scan_to_fit, b.scan_to_fit],
            kept,
            cpd_iterations: cpd.iterations,
            seconds: clock.elapsed().as_secs_f64(),
        };
        let mut chosen = if kept {
            second.diagnostics.prealign = first.diagnostics.prealign;
            second
        } else {
            first.diagnostics.stopped_by_callback |= stopped;
            first
        };
        chosen.diagnostics.coherent = Some(figures);
        Ok(chosen)
    }
}
