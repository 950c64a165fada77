//! The named presets and the candidate schedules of schedule selection.

use super::isometric::PlaneNormal;
use super::params::{
    FitParams, Method, Prealign, Selection, UnstretchedRefinement, ACCURATE_ITERATIONS,
    FAST_ITERATIONS, FAST_TWO_WAY, PAPER_ITERATIONS, PAPER_K_MAX, PAPER_RHO,
    TRACKING_ISOMETRIC_ITERATIONS, TRACKING_ITERATIONS, TRACKING_REST_RIGIDITY,
    TRACKING_STRAIN_LIMIT,
};
use crate::error::{FoldMatchError, Result};
use crate::nbody::TwoWayPull;
use crate::regularize::Regularization;

impl FitParams {
    /// The paper's method as printed, with only the converging readings (docs/method.md, "Ablation
    /// of the readings"): one-way attraction, no rigid or coarse phase, constant softening, Eq. 5
    /// as the affine-invariant mean, ρ = 0.2 % and K ≤ 64, 100 iterations and no isometric
    /// refinement or rim matching (the `"paper"` preset).
    pub fn paper() -> Self {
        let mut p = Self {
            iterations: PAPER_ITERATIONS,
            ..Self::default()
        }
        .without_isometric_refinement();
        p.model.rho = PAPER_RHO;
        p.model.k_max = PAPER_K_MAX;
        p.schedule.two_way = 0.0;
        p.schedule.rigid_fraction = 0.0;
        p.schedule.coarse_fraction = 0.0;
        p.schedule.rest_rigidity = 0.0;
        p.schedule.anneal = 1.0;
        p.schedule.anneal_fraction = 0.0;
        p.schedule.selection = Selection::Single;
        p.schedule.keep_margin = 0.0;
        p.schedule.garment_refit = 0.0;
        p.schedule.strain_limit = 0.0;
        p.schedule.carry_unsupported = 0.0;
        p.schedule.rim_weight = 0.0;
        p.schedule.coherent_gate = 0.0;
        p.readings.regularization = Regularization::AffineInvariant;
        p.prealign = Prealign::None;
        p
    }

    /// The default without softening annealing, for a fit that starts close to its scan
    /// (warm-started frames of a sequence): annealing is a far-start device and, with few
    /// iterations per frame, leaves too little time at the final ε (docs/method.md). Its
    /// two-way weight (2), averaged pulls ([`TwoWayPull::Mean`]) and rigid phase on every
    /// vertex are the values it was measured with on sequences. It keeps the default's
    /// rest-shape rigidity, whose rest shape in a sequence is the template, not the previous
    /// fit ([`crate::track`], docs/method.md "Tracking"): on the DiffCloth wind sequence it
    /// halves the largest per-frame error of tracking without it (`bench/tracking.py`). Its
    /// strain and compression limits (5 %) hold the metric of the rest shape, the first
    /// frame's own mesh, which simulated and captured cloth keeps within a few per cent.
    pub fn tracking() -> Self {
        let mut p = Self::default();
        p.schedule.two_way = 2.0;
        p.schedule.two_way_pull = TwoWayPull::Mean;
        p.acceleration.rigid_sample = 1;
        p.schedule.anneal = 1.0;
        p.schedule.anneal_fraction = 0.0;
        p.schedule.selection = Selection::Single;
        p.schedule.keep_margin = 0.0;
        p.schedule.strain_limit = TRACKING_STRAIN_LIMIT;
        p.schedule.compression_limit = TRACKING_STRAIN_LIMIT;
        p.schedule.isometric_iterations = TRACKING_ISOMETRIC_ITERATIONS;
        p.schedule.isometric_hold = 0.0;
        p.schedule.isometric_plane = PlaneNormal::Fit;
        // The isometric refinement holds the template's metric; the rest-shape rigidity, which
        // also holds its bends, only steadies the motion (docs/method.md "Tracking").
        p.schedule.rest_rigidity = TRACKING_REST_RIGIDITY;
        // A frame starts near its scan, and the refinement finishes it.
        p.iterations = TRACKING_ITERATIONS;
        // Every frame starts where the last one ended: placed already.
        p.prealign = Prealign::None;
        // A frame is anchored to its sequence's rest shape, not to a coherent one.
        p.schedule.coherent_gate = 0.0;
        p
    }

    /// The alternative schedule of [`Selection::ScanDistance`]: these parameters with a sharper
    /// schedule — two-way weight 1, coarse phase 30 %, constant softening — which fits gently
    /// curved, misplaced cloth (the random sheets) best, where the annealed default fits large
    /// articulated motion best.
    pub fn sharp_schedule(&self) -> Self {
        let mut p = self.clone();
        p.schedule.two_way = self.schedule.two_way.min(1.0);
        p.schedule.coarse_fraction = self.schedule.coarse_fraction.min(0.3);
        p.schedule.anneal = 1.0;
        p.schedule.anneal_fraction = 0.0;
        p.schedule.selection = Selection::Single;
        p
    }

    /// The third candidate of [`Selection::ScanDistanceWide`]: these parameters with ⅔ of the
    /// two-way weight (4.5 → 3) and the softening annealed over at least 80 % of the iterations
    /// (60 % in the default): long-range pulls for longer, a gentler pull on scan regions the
    /// template does not cover yet (docs/method.md).
    pub fn gentle_schedule(&self) -> Self {
        let mut p = self.clone();
        p.schedule.two_way = self.schedule.two_way / 1.5;
        p.schedule.anneal_fraction = self.schedule.anneal_fraction.max(0.8);
        p.schedule.selection = Selection::Single;
        p
    }

    /// The schedules a fit runs: the given one alone ([`Selection::Single`], or NRGa), or the
    /// candidates of schedule selection, named by [`SCHEDULE_NAMES`](super::SCHEDULE_NAMES).
    pub fn candidate_schedules(&self) -> Vec<Self> {
        let given = {
            let mut p = self.clone();
            p.schedule.selection = Selection::Single;
            p
        };
        match self.schedule.selection {
            _ if self.method != Method::FoldMatch => vec![given],
            Selection::Single => vec![given],
            Selection::ScanDistance => vec![given, self.sharp_schedule()],
            Selection::ScanDistanceWide => {
                vec![given, self.sharp_schedule(), self.gentle_schedule()]
            }
        }
    }

    /// The default with [`ACCURATE_ITERATIONS`] iterations instead of 80, every phase
    /// lengthened in proportion, and every fit that the schedule left unstretched refined to
    /// the rest shape's metric ([`UnstretchedRefinement::EveryFit`]; the default does so on
    /// the garment passes of a dressed scan only) (the `"accurate"` preset): closer to the
    /// truth and to the scan at about twice the time; more iterations alone still fit the scan
    /// closer but drift from the truth (docs/method.md, "Beyond the paper: the default
    /// configuration", "Isometric refinement").
    pub fn accurate() -> Self {
        let mut p = Self {
            iterations: ACCURATE_ITERATIONS,
            ..Self::default()
        };
        p.schedule.unstretched_refinement = UnstretchedRefinement::EveryFit;
        p
    }

    /// One schedule instead of schedule selection's two (the `"fast"` preset), between the
    /// given and the sharp one: the default's [`FitParams::sharp_schedule`] (a 30 % coarse
    /// phase, constant softening) with two-way weight [`FAST_TWO_WAY`]. About 0.7× the
    /// default's time (the second run, the comparison and the refinement are spared), at a
    /// higher error than the default's, and a lower one than either of the default's candidates
    /// alone
    /// (docs/method.md, "Beyond the paper: the default configuration"). It runs
    /// [`FAST_ITERATIONS`] iterations and no isometric refinement, which would cost it about
    /// 15 % more time. For previews and large batches where time comes first.
    pub fn fast() -> Self {
        let mut p = Self::default()
            .sharp_schedule()
            .without_isometric_refinement();
        p.schedule.two_way = FAST_TWO_WAY;
        p.iterations = FAST_ITERATIONS;
        // One fit: no coherent candidate.
        p.schedule.coherent_gate = 0.0;
        p
    }

    /// These parameters without the isometric refinement (no steps, no hold): the `"paper"`
    /// and `"fast"` presets.
    fn without_isometric_refinement(mut self) -> Self {
        self.schedule.isometric_iterations = 0;
        self.schedule.isometric_hold = 0.0;
        self
    }

    /// A named preset: `"default"` (the most accurate configuration for its cost, see
    /// docs/method.md), `"accurate"` ([`FitParams::accurate`]), `"fast"`
    /// ([`FitParams::fast`]), `"paper"` ([`FitParams::paper`]) or `"tracking"`
    /// ([`FitParams::tracking`]).
    pub fn preset(name: &str) -> Result<Self> {
        match name {
            "default" => Ok(Self::default()),
            "accurate" => Ok(Self::accurate()),
            "fast" => Ok(Self::fast()),
            "paper" => Ok(Self::paper()),
            "tracking" => Ok(Self::tracking()),
            other => Err(FoldMatchError::parameter(
                "preset",
                other,
                "one of default, accurate, fast, paper, tracking",
            )),
        }
    }
}
