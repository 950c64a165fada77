//! The NRG motion model (paper §2): scan points attract template points as an N-body system. The
//! force of Eq. 2 with its curvature term, and the damped integration of Eq. 3, in the converging
//! readings of docs/method.md "Force, Eq. 2" and "Integration, Eq. 3"; each literal reading of the
//! paper stays reachable through [`ForceNumerator`], [`ForceSum`] and [`DampingMode`].

use crate::knn::{ReverseNearest, TargetNeighbours};
use crate::math::{vec3, Vec3};
use rayon::prelude::*;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The numerator of Eq. 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ForceNumerator {
    /// `α_kj (Y_k − X_j)`: translation-invariant (default; docs/method.md "Force, Eq. 2").
    Centered,
    /// `Y_k α_kj − X_j`, as printed: depends on the origin.
    Literal,
}

/// How the per-neighbour forces are combined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ForceSum {
    /// Mean over the K neighbours, i.e. m(X_j) = 1/K (default; the sum overshoots, docs/method.md
    /// "Integration, Eq. 3").
    Mean,
    /// Plain sum, as printed.
    Sum,
}

/// How η dissipates velocity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DampingMode {
    /// `v ← (1 − η) v + F/m Δt`: η is the fraction of velocity dissipated per step (default).
    Fraction,
    /// `F ← F − η v`, as printed in Eq. 2 (dissipates only ηΔt per step).
    Force,
}

/// How the two-way attraction combines the pulls of the scan points choosing one template
/// point ([`ReverseAttraction`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum TwoWayPull {
    /// Their mean: a template point chosen by many scan points is pulled no harder than one
    /// chosen by a few (the literal reading).
    Mean,
    /// Their sum × M / N (template points over scan points): every scan point pulls with the same
    /// weight, so where the template covers the scan evenly (N / M points choosing each template
    /// point) this is the mean, and a template point standing for more than its share of the scan —
    /// at the edge of a scan region no other template point is near — is pulled harder, in
    /// proportion (default; docs/method.md, the two-way pulls summed by coverage).
    Coverage,
}

/// Constants of the N-body simulation (paper §4 defaults).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(default)]
pub struct NBodyParams {
    /// Gravitational constant G.
    pub gravity: f64,
    /// Softening length ε.
    pub softening: f64,
    /// Damping η.
    pub damping: f64,
    /// Time step Δt.
    pub time_step: f64,
    /// Template particle mass m(Y).
    pub template_mass: f64,
    /// Scan particle mass m(X).
    pub target_mass: f64,
    /// Positive floor applied to the curvature term α_kj (docs/method.md "Force, Eq. 2").
    pub alpha_floor: f64,
    /// Numerator reading of Eq. 2.
    pub numerator: ForceNumerator,
    /// Combination of neighbour forces.
    pub summation: ForceSum,
    /// Damping reading.
    pub damping_mode: DampingMode,
}

impl Default for NBodyParams {
    fn default() -> Self {
        Self {
            gravity: 1.67,
            softening: 0.1,
            damping: 0.1,
            time_step: 0.006,
            template_mass: 1.0,
            target_mass: 1.0,
            alpha_floor: 0.1,
            numerator: ForceNumerator::Centered,
            summation: ForceSum::Mean,
            damping_mode: DampingMode::Fraction,
        }
    }
}

impl NBodyParams {
    /// `(ω₀Δt)²` of the near-field spring for K neighbours: stiffness `K_eff·G·m(X)/ε³` per unit
    /// template mass, with `K_eff = 1` for [`ForceSum::Mean`] and K for [`ForceSum::Sum`]. Explicit
    /// integration overshoots when this approaches 1 (docs/method.md "Integration, Eq. 3").
    pub fn omega0_dt_squared(&self, k: usize) -> f64 {
        let k_eff = match self.summation {
            ForceSum::Mean => 1.0,
            ForceSum::Sum => k as f64,
        };
        k_eff * self.gravity * self.target_mass / self.softening.powi(3) * self.time_step.powi(2)
    }
}

/// The curvature term `α_kj = max(1 − ½ κ_j ‖Y_k − X_j‖², α_floor)`.
#[inline]
pub fn alpha(kappa: f64, dist2: f64, floor: f64) -> f64 {
    (1.0 - 0.5 * kappa * dist2).max(floor)
}

/// One term of the sum in Eq. 2: the pull of the scan point `x` (curvature `kappa`) on the
/// template point `y`.
#[inline]
pub fn pair_force(y: &Vec3, x: &Vec3, kappa: f64, p: &NBodyParams) -> Vec3 {
    let omega = p.gravity * p.template_mass * p.target_mass;
    let diff = y - x;
    let d2 = diff.norm_squared();
    let a = alpha(kappa, d2, p.alpha_floor);
    // The denominator (d² + ε²)^{3/2} α^{3/2} with one square root, s·a·√(s·a) (powf is
    // several times dearer), and one division for the three components.
    let soft = d2 + p.softening * p.softening;
    let root = (soft * a).sqrt();
    match p.numerator {
        // α (y − x) / (s^{3/2} α^{3/2}) = (y − x) / (s √(s α)).
        ForceNumerator::Centered => (-omega / (soft * root)) * diff,
        ForceNumerator::Literal => (-omega / (soft * a * root)) * (a * y - x),
    }
}

/// The gravitational part of Eq. 2 on one template point at `y` from its scan neighbours
/// `neighbours` (indices into `target`, with curvatures `kappa`), without the damping term.
pub fn gravitational_force(
    y: &Vec3,
    neighbours: &[u32],
    target: &[[f64; 3]],
    kappa: &[f64],
    p: &NBodyParams,
) -> Vec3 {
    weighted_gravitational_force(y, neighbours, target, kappa, None, None, p)
}

/// [`gravitational_force`] with a non-negative weight per scan point (`weights[j]`, the
/// user's scan weights): each neighbour's term is scaled by its weight and, under
/// [`ForceSum::Mean`], the mean becomes the weighted mean `Σ w_j F_j / Σ w_j` (zero when every
/// neighbour weighs 0). `None` is every weight 1. With `rim = (o, margin)` (a template point
/// on the boundary, `o` its outward direction in the surface), neighbours beyond the boundary
/// by more than `margin` weigh 0 ([`TwoWay::rim`]).
pub fn weighted_gravitational_force(
    y: &Vec3,
    neighbours: &[u32],
    target: &[[f64; 3]],
    kappa: &[f64],
    weights: Option<&[f64]>,
    rim: Option<(Vec3, f64)>,
    p: &NBodyParams,
) -> Vec3 {
    let weight = |j: usize| {
        let w = weights.map_or(1.0, |w| w[j]);
        match rim {
            Some((o, margin)) if (vec3(&target[j]) - y).dot(&o) > margin => 0.0,
            _ => w,
        }
    };
    if weights.is_some() || rim.is_some() {
        let (mut f, mut total) = (Vec3::zeros(), 0.0);
        for &j in neighbours {
            let wj = weight(j as usize);
            if wj > 0.0 {
                f += wj * pair_force(y, &vec3(&target[j as usize]), kappa[j as usize], p);
                total += wj;
            }
        }
        return match p.summation {
            ForceSum::Mean if total > 0.0 => f / total,
            ForceSum::Mean => Vec3::zeros(),
            ForceSum::Sum => f,
        };
    }
    {
        let mut f = Vec3::zeros();
        for &j in neighbours {
            f += pair_force(y, &vec3(&target[j as usize]), kappa[j as usize], p);
        }
        match p.summation {
            ForceSum::Mean if !neighbours.is_empty() => f / neighbours.len() as f64,
            _ => f,
        }
    }
}

/// One integration step (Eq. 2–3) for every template point, in parallel.
///
/// `neighbours` holds K scan indices per template point (row-major, M × K); `weights`, when
/// given, one weight per scan point ([`weighted_gravitational_force`]). `extra` is an
/// optional additional force per template point (the two-way attraction). Updates
/// `velocities` to `v^{t+Δt}` and writes the proposed positions `Y^t + v^{t+Δt} Δt` to
/// `proposed`.
#[allow(clippy::too_many_arguments)]
pub fn step(
    positions: &[[f64; 3]],
    velocities: &mut [[f64; 3]],
    neighbours: &[u32],
    k: usize,
    target: &[[f64; 3]],
    kappa: &[f64],
    weights: Option<&[f64]>,
    rim: Option<(&[[f64; 3]], f64)>,
    p: &NBodyParams,
    extra: Option<&[[f64; 3]]>,
    proposed: &mut [[f64; 3]],
) {
    let dt = p.time_step;
    velocities
        .par_iter_mut()
        .zip(proposed.par_iter_mut())
        .enumerate()
        .for_each(|(i, (vel, out))| {
            let y = vec3(&positions[i]);
            let v = vec3(vel);
            let row = &neighbours[i * k..(i + 1) * k];
            let rim = rim
                .map(|(out, margin)| (vec3(&out[i]), margin))
                .filter(|(o, _)| *o != Vec3::zeros());
            let mut f = weighted_gravitational_force(&y, row, target, kappa, weights, rim, p);
            if let Some(extra) = extra {
                f += vec3(&extra[i]);
            }
            let v_new = match p.damping_mode {
                DampingMode::Fraction => (1.0 - p.damping) * v + f / p.template_mass * dt,
                DampingMode::Force => v + (f - p.damping * v) / p.template_mass * dt,
            };
            *vel = v_new.into();
            *out = (y + v_new * dt).into();
        });
}

/// Two-way attraction: every scan point also pulls its nearest template point with the Eq. 2
/// kernel. The pulls on each template point are combined by [`TwoWayPull`] (their mean, or
/// their sum in proportion to the template's share of the scan) and scaled by `weight`.
///
/// Holds the per-fit scratch buffers. Each template point sums its pulls in increasing scan
/// order (the scan points are bucketed by their nearest template point with a counting sort),
/// so the result is the same for any thread count.
#[derive(Clone, Debug, Default)]
pub struct ReverseAttraction {
    queries: ReverseNearest,
    from_forward: bool,
    nearest: Vec<u32>,
    offsets: Vec<usize>,
    heads: Vec<usize>,
    order: Vec<u32>,
}

impl ReverseAttraction {
    /// Scratch for a template of `m` points and a scan of `n` points; `from_forward` derives
    /// the nearest template points from the forward k-NN lists where that is exact
    /// ([`ReverseNearest`]), else every scan point queries a tree over the template.
    pub fn new(m: usize, n: usize, from_forward: bool) -> Self {
        Self {
            queries: ReverseNearest::new(n),
            from_forward,
            nearest: vec![0; n],
            offsets: vec![0; m + 1],
            heads: vec![0; m],
            order: vec![0; n],
        }
    }

    /// The reverse forces on the template at `positions`, written to `out`; `forward` are the
    /// target neighborhoods of these positions. Returns the number of scan points whose nearest
    /// template point was queried against a k-d tree.
    #[allow(clippy::too_many_arguments)] // the stage inputs, the settings and the output
    pub fn compute(
        &mut self,
        positions: &[[f64; 3]],
        target: &[[f64; 3]],
        kappa: &[f64],
        forward: TargetNeighbours<'_>,
        two_way: &TwoWay<'_>,
        p: &NBodyParams,
        out: &mut [[f64; 3]],
    ) -> usize {
        let forward = self.from_forward.then_some(forward);
        let fresh = self
            .queries
            .query(positions, target, forward, &mut self.nearest);
        // Scan points beyond the trust radius, or weighing 0, pull nothing: they are left out
        // of the buckets (index `m`, past the last template point).
        let m = self.heads.len();
        let trust2 = two_way.trust_radius * two_way.trust_radius;
        let mut total = 0.0;
        for (j, k) in self.nearest.iter_mut().enumerate() {
            let w = two_way.weights.map_or(1.0, |w| w[j]);
            let (x, y) = (&target[j], &positions[*k as usize]);
            let beyond_rim = two_way.rim.is_some_and(|(out, margin)| {
                (vec3(x) - vec3(y)).dot(&vec3(&out[*k as usize])) > margin
            });
            if w > 0.0 && crate::math::dist2(x, y) <= trust2 && !beyond_rim {
                total += w;
            } else {
                *k = m as u32;
            }
        }
        // Counting sort of the scan points by nearest template point (stable: scan order).
        self.offsets.iter_mut().for_each(|o| *o = 0);
        for &k in self.nearest.iter().filter(|&&k| (k as usize) < m) {
            self.offsets[k as usize + 1] += 1;
        }
        for i in 1..self.offsets.len() {
            self.offsets[i] += self.offsets[i - 1];
        }
        self.heads.copy_from_slice(&self.offsets[..m]);
        for (j, &k) in self.nearest.iter().enumerate() {
            if (k as usize) < m {
                self.order[self.heads[k as usize]] = j as u32;
                self.heads[k as usize] += 1;
            }
        }
        let (offsets, order) = (&self.offsets, &self.order);
        // Per unit of scan weight, under `Coverage`: M / Σ w (the template's share of the
        // scan points that pull).
        let share = if total > 0.0 { m as f64 / total } else { 0.0 };
        let (weight, weights) = (two_way.weight, two_way.weights);
        out.par_iter_mut().enumerate().for_each(|(k, f)| {
            let mine = &order[offsets[k]..offsets[k + 1]];
            let (mut sum, mut mass) = (Vec3::zeros(), 0.0);
            for &j in mine {
                let j = j as usize;
                let w = weights.map_or(1.0, |w| w[j]);
                sum += w * pair_force(&vec3(&positions[k]), &vec3(&target[j]), kappa[j], p);
                mass += w;
            }
            let scale = match two_way.pull {
                _ if mine.is_empty() => 0.0,
                TwoWayPull::Mean => weight / mass,
                TwoWayPull::Coverage => weight * share,
            };
            *f = (sum * scale).into();
        });
        fresh
    }
}

/// The two-way attraction's settings for one iteration ([`ReverseAttraction::compute`]).
#[derive(Clone, Copy, Debug)]
pub struct TwoWay<'a> {
    /// The weight of the pulls (`FitParams::two_way`).
    pub weight: f64,
    /// How the pulls on one template point combine.
    pub pull: TwoWayPull,
    /// Scan points farther than this from their nearest template point pull nothing
    /// (`f64::INFINITY`: every point pulls): what the garment cannot explain — the skin
    /// beyond a hem or a cuff, another garment — must not drag the template (Turk & Levoy's
    /// rejection of distant pairs, docs/method.md "Scans of dressed people").
    pub trust_radius: f64,
    /// The template's rim: per template point its outward direction in the surface (unit on
    /// the boundary, zero inside), and a margin. A scan point whose nearest template point is
    /// on the boundary and that lies beyond it by more than the margin pulls nothing: the
    /// surface it belongs to continues past the garment's edge (skin below a hem, an arm out
    /// of a sleeve), which the template does not explain (Turk & Levoy 1994).
    pub rim: Option<(&'a [[f64; 3]], f64)>,
    /// One non-negative weight per scan point (`None`: every weight 1): each pull is scaled by
    /// its point's weight, and a mean is a weighted mean.
    pub weights: Option<&'a [f64]>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_force_equals_the_printed_formula() {
        // Eq. 2's term as printed, with powf: −G m m · numerator / ((d² + ε²)^{3/2} α^{3/2}).
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for numerator in [ForceNumerator::Centered, ForceNumerator::Literal] {
            let p = NBodyParams {
                numerator,
                ..Default::default()
            };
            for _ in 0..2000 {
                let mut point = || Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0));
                let (y, x) = (point(), point());
                let kappa = rng.random_range(-3.0..3.0);
                let d2 = (y - x).norm_squared();
                let a = alpha(kappa, d2, p.alpha_floor);
                let num = match numerator {
                    ForceNumerator::Centered => a * (y - x),
                    ForceNumerator::Literal => a * y - x,
                };
                let denom = (d2 + p.softening.powi(2)).powf(1.5) * a.powf(1.5);
                let printed = -p.gravity * p.template_mass * p.target_mass * num / denom;
                let got = pair_force(&y, &x, kappa, &p);
                assert!(
                    (got - printed).norm() <= 1e-13 * printed.norm(),
                    "{got:?} vs {printed:?}"
                );
            }
        }
    }

    #[test]
    fn single_pair_force_is_newtonian_far_away() {
        // κ = 0, far field: |F| → G m m / d² pointing to the attractor.
        let p = NBodyParams {
            softening: 1e-6,
            ..Default::default()
        };
        let f = gravitational_force(&Vec3::new(3.0, 0.0, 0.0), &[0], &[[0.0; 3]], &[0.0], &p);
        assert!((f.x + 1.67 / 9.0).abs() < 1e-9 && f.y == 0.0 && f.z == 0.0);
    }

    #[test]
    fn centered_force_is_translation_invariant_literal_is_not() {
        let target = [[0.1, 0.2, 0.0], [0.0, -0.1, 0.05]];
        let kappa = [2.0, -1.0];
        let y = Vec3::new(0.3, 0.1, -0.2);
        let shift = Vec3::new(5.0, -3.0, 1.0);
        let shifted: Vec<[f64; 3]> = target.iter().map(|t| (vec3(t) + shift).into()).collect();
        for (num, invariant) in [
            (ForceNumerator::Centered, true),
            (ForceNumerator::Literal, false),
        ] {
            let p = NBodyParams {
                numerator: num,
                ..Default::default()
            };
            let a = gravitational_force(&y, &[0, 1], &target, &kappa, &p);
            let b = gravitational_force(&(y + shift), &[0, 1], &shifted, &kappa, &p);
            assert_eq!((a - b).norm() < 1e-12, invariant, "{num:?}");
        }
    }

    #[test]
    fn mean_is_sum_over_k_and_alpha_is_floored() {
        let target = [[0.0; 3], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]];
        let y = Vec3::new(0.05, 0.05, 0.3);
        let kappa = [0.0, 1e6, -3.0];
        let mean = gravitational_force(&y, &[0, 1, 2], &target, &kappa, &NBodyParams::default());
        let sum_p = NBodyParams {
            summation: ForceSum::Sum,
            ..Default::default()
        };
        let sum = gravitational_force(&y, &[0, 1, 2], &target, &kappa, &sum_p);
        assert!((mean * 3.0 - sum).norm() < 1e-12);
        assert_eq!(alpha(1e6, 1.0, 0.1), 0.1);
        assert!(mean.iter().all(|x| x.is_finite()));
    }

    #[test]
    fn two_way_pulls_average_or_sum_in_proportion_to_the_scan_share() {
        // Two template points far apart; three scan points choose the first, one the second
        // (M / N = 1/2). The mean gives each point the mean of its pulls; coverage gives the
        // sum × M / N: 3/2 of the mean on the first, 1/2 on the second; with an even share
        // (two each) both rules agree.
        let p = NBodyParams::default();
        let template = [[0.0; 3], [10.0, 0.0, 0.0]];
        let uneven = [
            [-0.1, 0.0, 0.0],
            [0.0, 0.1, 0.0],
            [0.05, 0.0, 0.1],
            [10.1, 0.0, 0.0],
        ];
        let even = [uneven[0], uneven[1], uneven[3], [9.9, 0.05, 0.0]];
        let kappa = [0.5, -1.0, 0.0, 2.0];
        let pull = |target: &[[f64; 3]], rule: TwoWayPull| {
            let mut reverse = ReverseAttraction::new(2, 4, false);
            let forward = TargetNeighbours {
                indices: &[0, 0],
                dist2: &[0.0, 0.0],
                k: 1,
                exact: true,
            };
            let mut out = [[0.0; 3]; 2];
            let two_way = TwoWay {
                weight: 2.0,
                pull: rule,
                trust_radius: f64::INFINITY,
                rim: None,
                weights: None,
            };
            reverse.compute(&template, target, &kappa, forward, &two_way, &p, &mut out);
            out.map(|f| vec3(&f))
        };
        let pair = |k: usize, j: usize, target: &[[f64; 3]]| {
            pair_force(&vec3(&template[k]), &vec3(&target[j]), kappa[j], &p)
        };
        let sum0: Vec3 = (0..3).map(|j| pair(0, j, &uneven)).sum();
        let mean = pull(&uneven, TwoWayPull::Mean);
        let coverage = pull(&uneven, TwoWayPull::Coverage);
        assert!((mean[0] - sum0 * (2.0 / 3.0)).norm() < 1e-12);
        assert!((coverage[0] - sum0).norm() < 1e-12, "2 × ½ × the sum");
        assert!((coverage[0] - 1.5 * mean[0]).norm() < 1e-12);
        assert!((coverage[1] - 0.5 * mean[1]).norm() < 1e-12);
        assert!((mean[1] - 2.0 * pair(1, 3, &uneven)).norm() < 1e-12);
        let (mean, coverage) = (
            pull(&even, TwoWayPull::Mean),
            pull(&even, TwoWayPull::Coverage),
        );
        for k in 0..2 {
            assert!(mean[k].norm() > 0.0 && (mean[k] - coverage[k]).norm() < 1e-12);
        }
    }

    #[test]
    fn damping_readings() {
        let pos = [[0.0; 3]];
        let target = [[0.0; 3]];
        for (mode, want) in [
            (DampingMode::Fraction, 0.9),
            (DampingMode::Force, 1.0 - 0.1 * 0.006),
        ] {
            let p = NBodyParams {
                damping_mode: mode,
                ..Default::default()
            };
            let mut vel = [[1.0, 0.0, 0.0]];
            let mut out = [[0.0; 3]];
            // Target at the point itself: zero force, only damping acts.
            step(
                &pos,
                &mut vel,
                &[0],
                1,
                &target,
                &[0.0],
                None,
                None,
                &p,
                None,
                &mut out,
            );
            assert!((vel[0][0] - want).abs() < 1e-15, "{mode:?}");
            assert!((out[0][0] - want * 0.006).abs() < 1e-15);
        }
    }

    #[test]
    fn omega_report() {
        let p = NBodyParams::default();
        assert!((p.omega0_dt_squared(28) - 0.060_12).abs() < 1e-4);
        let s = NBodyParams {
            summation: ForceSum::Sum,
            ..p
        };
        assert!((s.omega0_dt_squared(28) - 1.683).abs() < 1e-3);
    }
}
