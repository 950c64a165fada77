//! # FoldMatch
//!
//! Fits a garment template mesh onto a 3D scan (point cloud or mesh) so that folds, creases and
//! wrinkles of the scan are captured by a mesh of fixed topology. Implements *FoldMatch:
//! accurate and high fidelity garment fitting onto 3D scans* (the NRG N-body motion model, §2,
//! and the FoldMatch deformation model, §3), with the readings documented in `docs/method.md`.
//!
//! The pipeline, one module per stage, in the order a fit runs them:
//!
//! 1. [`normalize`] — the normalized frame the paper's constants assume;
//! 2. [`knn`] — target neighborhoods Γᵏ_X (k-d tree over the scan);
//! 3. [`curvature`] — Gaussian curvature κ of the target (mesh or point cloud);
//! 4. [`nbody`] — the gravitational force (Eq. 2) and the integration step (Eq. 3);
//! 5. [`rings`] — template n-ring neighborhoods Γᵏ_Y (CSR);
//! 6. [`deformation`] — deformation gradients H_k (Eq. 4);
//! 7. [`regularize`] — tensor-interpolation regularization (Eq. 5);
//! 8. [`wrinkle`] — polar decomposition, ψ-modified stretch and the wrinkle-vector field
//!    (Eq. 6–7);
//! 9. [`rotation`] — co-rotational rotation solve and translation (Eq. 8), per-vertex update;
//! 10. [`mod@fit`] — the driver: ξ iterations of the above, FoldMatch and NRGa modes.
//!
//! [`math`] holds the 3×3 algebra shared by all stages, [`mesh`] the template mesh checks and
//! geometry, [`error`] the error type.
#![warn(missing_docs)]

#[cfg(feature = "cli")]
pub mod cli;
pub mod cpd;
pub mod curvature;
pub mod deformation;
pub mod error;
pub mod fit;
pub mod io;
pub mod knn;
pub mod landmarks;
pub mod limits;
pub mod math;
pub mod mesh;
pub mod metrics;
pub mod min_cut;
pub mod nbody;
pub mod normalize;
pub mod prealign;
pub mod quality;
pub mod regularize;
#[cfg(feature = "render")]
pub mod render;
pub mod rings;
pub mod rotation;
pub mod synthetic;
pub mod track;
pub mod wrinkle;

#[cfg(feature = "python")]
mod python;

pub use error::{FoldMatchError, Result};
pub use fit::{fit, FitParams, FitResult, Method};
