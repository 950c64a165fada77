//! Reading [`FitParams`] from JSON and checking every parameter's range, with errors that name
//! the parameter.

use super::params::{FitParams, MAX_SCAN_SAMPLE};
use crate::error::{FoldMatchError, Result};
use crate::limits::{MAX_ITERATIONS, MAX_K, MAX_PARAMETER};

/// A real parameter's allowed range ([`FitParams::validate`]): the test and the rule it states.
#[derive(Clone, Copy)]
struct Range {
    contains: fn(f64) -> bool,
    rule: &'static str,
}

// The unbounded real parameters stop at `limits::MAX_PARAMETER` (10⁶): they act in the
// normalized frame, where larger values only throw the template out of the scan's range.
const POSITIVE: Range = Range {
    contains: |v| v > 0.0 && v <= MAX_PARAMETER,
    rule: "must be in (0, 1e6]",
};
const NON_NEGATIVE: Range = Range {
    contains: |v| (0.0..=MAX_PARAMETER).contains(&v),
    rule: "must be in [0, 1e6]",
};
const UNIT: Range = Range {
    contains: |v| (0.0..=1.0).contains(&v),
    rule: "must be in [0, 1]",
};
const OPEN_UNIT: Range = Range {
    contains: |v| v > 0.0 && v <= 1.0,
    rule: "must be in (0, 1]",
};
const PSI: Range = Range {
    contains: |v| v.is_finite() && v.abs() < 1.0,
    rule: "must be finite with |psi| < 1",
};
const AT_LEAST_ONE: Range = Range {
    contains: |v| (1.0..=MAX_PARAMETER).contains(&v),
    rule: "must be in [1, 1e6]",
};

impl FitParams {
    /// Parses parameters from a JSON object; missing keys take their defaults, unknown keys are
    /// an error naming the key.
    pub fn from_json(text: &str) -> Result<Self> {
        Self::from_json_over(text, Self::default())
    }

    /// Like [`FitParams::from_json`], with missing keys taken from `base` (a preset).
    pub fn from_json_over(text: &str, base: Self) -> Result<Self> {
        let mut given: serde_json::Map<String, serde_json::Value> = serde_json::from_str(text)
            .map_err(|e| {
                FoldMatchError::parameter("params", short(text), &format!("not a JSON object: {e}"))
            })?;
        let known = serde_json::to_value(Self::default()).expect("FitParams serializes");
        let known = known.as_object().expect("FitParams is an object");
        if let Some(bad) = given.keys().find(|k| !known.contains_key(*k)) {
            let names: Vec<&str> = known.keys().map(String::as_str).collect();
            return Err(FoldMatchError::parameter(
                bad,
                "?",
                &format!("unknown parameter; known: {}", names.join(", ")),
            ));
        }
        let base = serde_json::to_value(base).expect("FitParams serializes");
        for (key, value) in base.as_object().expect("object") {
            given.entry(key.clone()).or_insert_with(|| value.clone());
        }
        let params: Self = serde_json::from_value(serde_json::Value::Object(given.clone()))
            .map_err(|e| Self::blame(&given, &base, e))?;
        params.validate()?;
        Ok(params)
    }

    /// The error of a parameter object that does not deserialize, naming the first key whose
    /// value alone makes `base` fail (and only that key and value, not the whole object).
    fn blame(
        given: &serde_json::Map<String, serde_json::Value>,
        base: &serde_json::Value,
        whole: serde_json::Error,
    ) -> FoldMatchError {
        for (key, value) in given {
            let mut one = base.clone();
            one[key.as_str()] = value.clone();
            if let Err(e) = serde_json::from_value::<Self>(one) {
                let shown = match value {
                    serde_json::Value::String(s) => short(s),
                    other => short(&other.to_string()),
                };
                let non_finite = matches!(
                    shown.to_ascii_lowercase().trim_start_matches(['+', '-']),
                    "nan" | "inf" | "infinity" | "null"
                );
                let reason = if non_finite {
                    "must be a finite number".to_string()
                } else {
                    let e = e.to_string();
                    // serde's message ends with " at line L column C" of a text we made.
                    e.split(" at line ").next().unwrap_or(&e).to_string()
                };
                return FoldMatchError::parameter(key, shown, &reason);
            }
        }
        FoldMatchError::parameter("params", "?", &whole.to_string())
    }

    /// The parameters as a JSON object (every key, defaults included).
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("FitParams serializes")
    }

    /// Checks every parameter's range.
    pub fn validate(&self) -> Result<()> {
        let p = &self.model.nbody;
        if !(1..=MAX_ITERATIONS).contains(&self.iterations) {
            return Err(FoldMatchError::parameter(
                "iterations",
                self.iterations,
                &format!("must be in 1..={MAX_ITERATIONS}"),
            ));
        }
        // Every real-valued parameter's range.
        let rules = [
            ("rho", self.model.rho, POSITIVE),
            ("gravity", p.gravity, POSITIVE),
            ("softening", p.softening, POSITIVE),
            ("time_step", p.time_step, POSITIVE),
            ("template_mass", p.template_mass, POSITIVE),
            ("target_mass", p.target_mass, POSITIVE),
            ("alpha_floor", p.alpha_floor, OPEN_UNIT),
            ("psi", self.model.psi, PSI),
            ("selection_at", self.schedule.selection_at, OPEN_UNIT),
            (
                "normal_completion",
                self.model.normal_completion,
                NON_NEGATIVE,
            ),
            ("tolerance", self.tolerance, NON_NEGATIVE),
            (
                "selection_margin",
                self.schedule.selection_margin,
                NON_NEGATIVE,
            ),
            ("keep_margin", self.schedule.keep_margin, NON_NEGATIVE),
            ("garment_refit", self.schedule.garment_refit, NON_NEGATIVE),
            ("garment_cut", self.schedule.garment_cut, NON_NEGATIVE),
            ("strain_limit", self.schedule.strain_limit, NON_NEGATIVE),
            (
                "compression_limit",
                self.schedule.compression_limit,
                NON_NEGATIVE,
            ),
            (
                "isometric_weight",
                self.schedule.isometric_weight,
                NON_NEGATIVE,
            ),
            ("isometric_hold", self.schedule.isometric_hold, NON_NEGATIVE),
            ("rim_weight", self.schedule.rim_weight, NON_NEGATIVE),
            ("coherent_gate", self.schedule.coherent_gate, NON_NEGATIVE),
            (
                "carry_unsupported",
                self.schedule.carry_unsupported,
                NON_NEGATIVE,
            ),
            ("two_way", self.schedule.two_way, NON_NEGATIVE),
            ("two_way_trust", self.schedule.two_way_trust, NON_NEGATIVE),
            ("two_way_rim", self.schedule.two_way_rim, NON_NEGATIVE),
            ("landmark_weight", self.landmark_weight, NON_NEGATIVE),
            ("damping", p.damping, UNIT),
            ("knn_slack", self.acceleration.knn_slack, UNIT),
            ("rigid_fraction", self.schedule.rigid_fraction, UNIT),
            ("coarse_fraction", self.schedule.coarse_fraction, UNIT),
            ("anneal_fraction", self.schedule.anneal_fraction, UNIT),
            ("rest_rigidity", self.schedule.rest_rigidity, UNIT),
            ("anneal", self.schedule.anneal, AT_LEAST_ONE),
        ];
        for (name, v, range) in rules {
            if !(range.contains)(v) {
                return Err(FoldMatchError::parameter(name, shown(v), range.rule));
            }
        }
        if self.schedule.rigid_fraction + self.schedule.coarse_fraction > 1.0 {
            return Err(FoldMatchError::parameter(
                "rigid_fraction + coarse_fraction",
                self.schedule.rigid_fraction + self.schedule.coarse_fraction,
                "must be <= 1",
            ));
        }
        if !(1..=4).contains(&self.schedule.coarse_levels) {
            return Err(FoldMatchError::parameter(
                "coarse_levels",
                self.schedule.coarse_levels,
                "must be in 1..=4",
            ));
        }
        if !(1..=64).contains(&self.acceleration.coarse_sample) {
            return Err(FoldMatchError::parameter(
                "coarse_sample",
                self.acceleration.coarse_sample,
                "must be in 1..=64",
            ));
        }
        // The smallest radius any template gets (the automatic one grows with the size).
        let smallest_radius = self.coarse_radius(0);
        if self.acceleration.coarse_sample > 1
            && (smallest_radius >> (self.schedule.coarse_levels.max(1) - 1)) < 3
        {
            return Err(FoldMatchError::parameter(
                "coarse_sample",
                self.acceleration.coarse_sample,
                "needs coarse rings of radius >= 3 at every level (coarse_rings / 2^(coarse_levels-1))",
            ));
        }
        for (name, value) in [
            ("rigid_scan_sample", self.acceleration.rigid_scan_sample),
            ("coarse_scan_sample", self.acceleration.coarse_scan_sample),
        ] {
            if value > MAX_SCAN_SAMPLE {
                return Err(FoldMatchError::parameter(
                    name,
                    value,
                    &format!("must be in 0..={MAX_SCAN_SAMPLE} (0: automatic)"),
                ));
            }
        }
        if !(1..=64).contains(&self.acceleration.rigid_sample) {
            return Err(FoldMatchError::parameter(
                "rigid_sample",
                self.acceleration.rigid_sample,
                "must be in 1..=64",
            ));
        }
        if self.schedule.coarse_rings > 32 {
            return Err(FoldMatchError::parameter(
                "coarse_rings",
                self.schedule.coarse_rings,
                "must be in 0..=32 (0: automatic)",
            ));
        }
        if !(1..=8).contains(&self.model.rings) {
            return Err(FoldMatchError::parameter(
                "rings",
                self.model.rings,
                "must be in 1..=8",
            ));
        }
        if self.model.k_min == 0 || self.model.k_max < self.model.k_min || self.model.k_max > MAX_K
        {
            return Err(FoldMatchError::parameter(
                "k_min/k_max",
                format!("{}/{}", self.model.k_min, self.model.k_max),
                &format!("need 1 <= k_min <= k_max <= {MAX_K}"),
            ));
        }
        Ok(())
    }
}

/// A value for an error message: plain (`2`, `0.25`) in the usual range, else in the shortest
/// form that reads back (`1e300`, not 301 digits; `NaN`).
pub(super) fn shown(v: f64) -> String {
    if v == 0.0 || (v.is_finite() && (1e-6..1e15).contains(&v.abs())) {
        format!("{v}")
    } else {
        format!("{v:?}")
    }
}

/// `text`, or its first 60 characters and an ellipsis (for error messages).
pub(super) fn short(text: &str) -> String {
    match text.char_indices().nth(60) {
        Some((i, _)) => format!("{}…", &text[..i]),
        None => text.to_string(),
    }
}
