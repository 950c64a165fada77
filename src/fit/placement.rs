//! Where a fit starts (docs/method.md "Global pre-alignment", "Landmarks"): the template
//! moved by the global pre-alignment, the fits from its two readings of a garment that rigid
//! scores cannot tell apart, and the placement by landmarks.

use super::{
    fit_from, kept_points, FitParams, FitResult, FitRole, Prealign, PrealignFigures, Progress,
    SIZE_MISMATCH,
};
use crate::error::{FoldMatchError, Result};
use crate::landmarks::Landmarks;

/// The fits from two placements of the template (the pre-alignment's readings, in the
/// scan's frame), without a pre-alignment of their own; the second replaces the first when its
/// fit lies closer to the scan by [`READING_MARGIN`] (the sum of the two directed distances,
/// every vertex counted), returned with `prealign`'s figures and which placement it is from.
/// Each reports its half of the progress.
pub(super) fn fit_readings(
    placements: [&[[f64; 3]]; 2],
    placed_fit: &PlacedFit<'_>,
    prealign: Option<PrealignFigures>,
    observer: &mut (dyn FnMut(&Progress) -> bool + Send),
) -> Result<(FitResult, usize)> {
    // Over every vertex: a reading must not win by the vertices it carried (the verdict's
    // own fit → scan distance leaves those out).
    let closeness = |r: &FitResult| {
        let fit_to_scan = r.residuals.iter().sum::<f64>() / r.residuals.len().max(1) as f64;
        fit_to_scan / r.quality.scan_diagonal + r.quality.scan_to_fit
    };
    // Each fit with its distance (one when the observer stopped the first).
    let mut fits: Vec<(FitResult, f64)> = Vec::with_capacity(2);
    for (part, placement) in placements.into_iter().enumerate() {
        let fitted = placed_fit.run(placement, part, prealign, observer)?;
        let stopped = fitted.diagnostics.stopped_by_callback;
        let distance = closeness(&fitted);
        fits.push((fitted, distance));
        if stopped {
            break;
        }
    }
    let replaced = fits.len() == 2 && fits[1].1 < (1.0 - READING_MARGIN) * fits[0].1;
    let other = fits.get(usize::from(!replaced)).map(|f| f.1);
    let (mut kept, distance) = fits.swap_remove(usize::from(replaced));
    // Both fitted: how far the other one ended from the kept one.
    if let Some(other) = other.filter(|o| o.is_finite() && distance > 0.0) {
        if let Some(figures) = kept.diagnostics.prealign.as_mut() {
            figures.reading_gap = Some(other / distance - 1.0);
        }
    }
    Ok((kept, usize::from(replaced)))
}

/// A fit of the template from a placement the pre-alignment found (the similarity's probe, a
/// reading): `fit_from` without a pre-alignment of its own, one half of the progress, its
/// result with the caller's parameters and the pre-alignment's figures.
pub(super) struct PlacedFit<'a> {
    pub(super) rest: Option<&'a [[f64; 3]]>,
    pub(super) template_faces: &'a [[u32; 3]],
    pub(super) target: &'a [[f64; 3]],
    pub(super) target_faces: Option<&'a [[u32; 3]]>,
    pub(super) target_weights: Option<&'a [f64]>,
    pub(super) target_normals: Option<&'a [[f64; 3]]>,
    pub(super) role: FitRole<'a>,
    pub(super) params: &'a FitParams,
}

impl PlacedFit<'_> {
    /// The fit from `placement` (`judged_on`: the template its verdict measures it against
    /// when not its rest shape, [`FitRole::judged_on`]), reporting to `observer` as a fit of
    /// its own, with the caller's parameters.
    pub(super) fn fit(
        &self,
        placement: &[[f64; 3]],
        judged_on: Option<&[[f64; 3]]>,
        observer: &mut (dyn FnMut(&Progress) -> bool + Send),
    ) -> Result<FitResult> {
        let mut inner = self.params.clone();
        inner.prealign = Prealign::None;
        // Its caller decides on the coherent candidate, once it has chosen among such fits.
        inner.schedule.coherent_gate = 0.0;
        let mut fitted = fit_from(
            placement,
            self.rest,
            self.template_faces,
            self.target,
            self.target_faces,
            self.target_weights,
            self.target_normals,
            None,
            FitRole {
                judged_on: judged_on.or(self.role.judged_on),
                ..self.role
            },
            &inner,
            observer,
        )?;
        fitted.params = self.params.clone();
        Ok(fitted)
    }

    /// The fit from `placement`, reporting half `part` (0 or 1) of the progress, with
    /// `prealign`'s figures.
    pub(super) fn run(
        &self,
        placement: &[[f64; 3]],
        part: usize,
        prealign: Option<PrealignFigures>,
        observer: &mut (dyn FnMut(&Progress) -> bool + Send),
    ) -> Result<FitResult> {
        let total = self.params.iterations;
        let mut half = |p: &Progress| observer(&p.of_parts(part, 2, total));
        let mut fitted = self.fit(placement, None, &mut half)?;
        fitted.diagnostics.prealign = prealign;
        Ok(fitted)
    }
}

/// The template as the pre-alignment moved it (`None`: as given), what the search found
/// (`None`: it did not run), and the template placed by the other reading to fit from too
/// ([`crate::prealign::Alignment::alternative`]).
type Placement = (
    Option<Vec<[f64; 3]>>,
    Option<PrealignFigures>,
    Option<Vec<[f64; 3]>>,
);

/// The other reading's fit replaces the first (the least turned) only when it lies closer to
/// the scan by this share: a garment fitted back to front can wrap its scan as closely (0.2–1.2
/// % closer than the right reading on the bent-over T-shirt, a folded one and a square sheet
/// of the harness), the right reading of a garment turned 90° lies 5–24 % closer than the
/// wrong one (`bench/prealign.py`; docs/notes/prealign-readings.md).
pub const READING_MARGIN: f64 = 0.04;

/// The template moved by the global pre-alignment of [`FitParams::prealign`] (`Rigid`,
/// `Similarity`: [`crate::prealign::align`] onto the scan points that remain), so that the fit,
/// and its result, are in the scan's frame as given (`None` when the template stays as given),
/// and what the search found (`None` when it did not run).
pub(super) fn prealigned(
    template_vertices: &[[f64; 3]],
    target: &[[f64; 3]],
    kept: Option<&[usize]>,
    params: &FitParams,
) -> Result<Placement> {
    let motion = match params.prealign {
        Prealign::Rigid => crate::prealign::Motion::Rigid,
        Prealign::Similarity => crate::prealign::Motion::Similarity,
        Prealign::None | Prealign::Centroid => return Ok((None, None, None)),
    };
    crate::mesh::validate_points("template_vertices", template_vertices)?;
    crate::mesh::validate_points("target", target)?;
    let scan = kept_points(target, kept);
    let scan = &scan[..];
    if motion == crate::prealign::Motion::Rigid {
        let ratio =
            crate::metrics::bbox_diagonal(template_vertices) / crate::metrics::bbox_diagonal(scan);
        if !(1.0 / SIZE_MISMATCH..=SIZE_MISMATCH).contains(&ratio) {
            return Err(FoldMatchError::SizeMismatch { ratio });
        }
    }
    let alignment = crate::prealign::align(template_vertices, scan, motion);
    let moved = !alignment.transform.is_identity();
    let figures = PrealignFigures {
        searched: alignment.searched,
        moved,
        identity_score: alignment.identity_score,
        score: alignment.score,
        best_score: alignment.best_score,
        readings_placed: [Some(alignment.transform), alignment.alternative],
        readings: alignment.readings,
        fitted_readings: match (alignment.searched, alignment.alternative) {
            (false, _) => 0,
            (true, Some(_)) if moved => 2,
            (true, _) => 1,
        },
        scale_stretch: 1.0,
        reading_gap: None,
    };
    Ok((
        moved.then(|| alignment.transform.apply_all(template_vertices)),
        Some(figures),
        alignment
            .alternative
            .filter(|_| moved)
            .map(|t| t.apply_all(template_vertices)),
    ))
}

/// Where landmarks place the template (docs/method.md "Landmarks"): three or more, not on a
/// line, by the rigid fit (with `scaled`, the similarity) of their vertices onto their targets;
/// fewer, with a searching pre-alignment ([`FitParams::prealign`] `Rigid` or `Similarity`), at
/// the search's placement that puts them nearest their targets
/// ([`crate::prealign::align_by_landmarks`], on the scan points that remain, `kept`); else by
/// the translation of their centroid.
pub(crate) fn landmark_placement(
    template_vertices: &[[f64; 3]],
    target: &[[f64; 3]],
    kept: Option<&[usize]>,
    landmarks: &Landmarks,
    params: &FitParams,
    scaled: bool,
) -> crate::prealign::Similarity {
    let searched = matches!(params.prealign, Prealign::Rigid | Prealign::Similarity);
    let from = landmarks.on(template_vertices);
    let fitted = || crate::landmarks::fit_similarity(&from, &landmarks.positions, scaled);
    if crate::landmarks::fixes_rotation(&from) || !searched {
        return fitted();
    }
    let motion = if scaled {
        crate::prealign::Motion::Similarity
    } else {
        crate::prealign::Motion::Rigid
    };
    let scan = kept_points(target, kept);
    crate::prealign::align_by_landmarks(
        template_vertices,
        &scan,
        motion,
        &from,
        &landmarks.positions,
    )
    .unwrap_or_else(fitted)
}
