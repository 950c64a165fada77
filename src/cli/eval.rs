//! `foldmatch eval`: the paper's metrics (paper §4) of a fitted mesh, as JSON on standard output.

use super::args::EvalCmd;
use super::job::{read_named, ScanWeights};
use super::report::write_json;
use super::{exit_code, Context};
use crate::fit::validate_weights;
use crate::metrics::{evaluate_weighted, MetricsInput, MetricsParams};
use std::io::Write;

/// Runs `eval`.
pub fn eval(cmd: &EvalCmd, ctx: &Context) -> i32 {
    match run(cmd, ctx) {
        Ok(()) => exit_code::OK,
        Err(e) => {
            ctx.ui.error(e);
            exit_code::FATAL
        }
    }
}

fn run(cmd: &EvalCmd, ctx: &Context) -> Result<(), String> {
    let template = read_named("template", &cmd.template)?;
    let fitted = read_named("fitted mesh", &cmd.fitted)?;
    let source = ScanWeights::from_options(
        cmd.scan_weights.as_ref(),
        cmd.scan_weights_property.as_ref(),
    );
    let (scan, weights) = match &source {
        None => (read_named("scan", &cmd.scan)?, None),
        Some(source) => {
            let (scan, weights, _, what) = source.read(&cmd.scan)?;
            validate_weights(&weights, scan.vertices.len()).map_err(|e| format!("{what}: {e}"))?;
            (scan, Some(weights))
        }
    };
    let gt = cmd
        .gt
        .as_ref()
        .map(|p| read_named("ground truth", p))
        .transpose()?;
    let m = template.vertices.len();
    let check = |what: &str, path: &std::path::Path, count: usize| {
        if count == m {
            Ok(())
        } else {
            Err(format!(
                "{what} {} has {count} vertices, but the template {} has {m} (vertex i must be template vertex i)",
                path.display(),
                cmd.template.display()
            ))
        }
    };
    check("fitted mesh", &cmd.fitted, fitted.vertices.len())?;
    if let (Some(g), Some(path)) = (&gt, &cmd.gt) {
        check("ground truth", path, g.vertices.len())?;
    }
    let defaults = MetricsParams::default();
    let params = MetricsParams {
        tau_s: cmd.tau_s.unwrap_or(defaults.tau_s),
        tau_e: cmd.tau_e.unwrap_or(defaults.tau_e),
        ..defaults
    };
    let input = MetricsInput {
        template_vertices: &template.vertices,
        faces: &template.faces,
        fitted_vertices: &fitted.vertices,
        target: &scan.vertices,
        ground_truth: gt.as_ref().map(|g| g.vertices.as_slice()),
    };
    let metrics = ctx
        .pool
        .install(|| evaluate_weighted(&input, weights.as_deref(), &params))
        .map_err(|e| e.to_string())?;
    let json = serde_json::to_string_pretty(&metrics).map_err(|e| e.to_string())?;
    // A closed stdout (a reader that quit) loses the figures; `println!` would panic.
    let _ = writeln!(std::io::stdout().lock(), "{json}");
    if let Some(path) = &cmd.output {
        write_json(path, &metrics)?;
        ctx.ui.info(format_args!("wrote {}", path.display()));
    }
    Ok(())
}
