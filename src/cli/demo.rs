//! `foldmatch demo`: the built-in example. A flat sheet template and the same sheet with
//! folds, rotated and offset, sampled into a noisy scan ([`crate::synthetic::folded_sheet`]);
//! the fit's outputs are written next to the inputs and the before/after figures printed.

use super::args::DemoCmd;
use super::job::{Job, Runner, Template};
use super::report::{write_json, FitReport, Status};
use super::{exit_code, Context};
use crate::io::{write_mesh, MeshData};
use crate::metrics::{evaluate, Metrics, MetricsInput, MetricsParams};
use crate::synthetic::{folded_sheet, SheetSpec};
use std::io::Write;

/// Runs `demo`.
pub fn demo(cmd: &DemoCmd, ctx: &Context) -> i32 {
    match run(cmd, ctx) {
        Ok(code) => code,
        Err(e) => {
            ctx.ui.error(e);
            exit_code::FATAL
        }
    }
}

fn run(cmd: &DemoCmd, ctx: &Context) -> Result<i32, String> {
    let ui = &ctx.ui;
    let params = cmd.params.to_params()?;
    if !(cmd.noise.is_finite() && cmd.noise >= 0.0) {
        return Err(format!("--noise {}: must be finite and >= 0", cmd.noise));
    }
    let n = cmd.size as usize;
    let spec = SheetSpec {
        nx: n,
        ny: n,
        scan_points: cmd.scan_points as usize,
        noise: cmd.noise,
        ..SheetSpec::default()
    };
    let case = folded_sheet(&spec);
    let dir = &cmd.output;
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let (template_path, scan_path, gt_path, fitted_path, report_path, preview_path) = (
        dir.join("template.ply"),
        dir.join("scan.ply"),
        dir.join("ground_truth.ply"),
        dir.join("fitted.ply"),
        dir.join("report.json"),
        dir.join("preview.png"),
    );
    let write = |path: &std::path::Path, mesh: &MeshData| {
        write_mesh(path, mesh, &[], false).map_err(|e| e.to_string())
    };
    write(
        &template_path,
        &MeshData::new(case.template_vertices.clone(), case.faces.clone()),
    )?;
    write(&scan_path, &MeshData::point_cloud(case.scan.clone()))?;
    write(
        &gt_path,
        &MeshData::new(case.ground_truth.clone(), case.faces.clone()),
    )?;

    let template = Template::new(
        &template_path,
        case.template_vertices.clone(),
        case.faces.clone(),
        &params,
    )?;
    let runner = Runner {
        template: &template,
        params: &params,
        ui,
        pool: &ctx.pool,
    };
    ui.info(format_args!(
        "demo: fitting {} ({} iterations) …",
        fitted_path.display(),
        params.iterations
    ));
    let outcome = runner.run(&Job {
        stage: None,
        name: "scan.ply".into(),
        scan: scan_path.clone(),
        output: fitted_path.clone(),
        gt: Some(gt_path.clone()),
        tracker: None,
        ascii: false,
        weights: None,
        preview: Some(preview_path.clone()),
        garment_mask: None,
        landmarks: None,
        scan_normals: false,
    });
    let report = FitReport {
        foldmatch_version: env!("CARGO_PKG_VERSION"),
        command: "demo",
        template: template_path.display().to_string(),
        file: &outcome.report,
        params: serde_json::to_value(&params).unwrap_or_default(),
    };
    write_json(&report_path, &report)?;
    match outcome.report.status {
        Status::Ok => {}
        Status::Interrupted => return Ok(exit_code::INTERRUPTED),
        _ => return Err(outcome.report.error.unwrap_or_default()),
    }
    let after = outcome.metrics.ok_or("metrics could not be computed")?;
    let before = ctx
        .pool
        .install(|| {
            evaluate(
                &MetricsInput {
                    template_vertices: &case.template_vertices,
                    faces: &case.faces,
                    fitted_vertices: &case.template_vertices,
                    target: &case.scan,
                    ground_truth: Some(&case.ground_truth),
                },
                &MetricsParams::default(),
            )
        })
        .map_err(|e| e.to_string())?;
    print_figures(cmd, &case.faces, &before, &after, &outcome.report, &params);
    Ok(exit_code::OK)
}

fn print_figures(
    cmd: &DemoCmd,
    faces: &[[u32; 3]],
    before: &Metrics,
    after: &Metrics,
    report: &super::report::FileReport,
    params: &crate::fit::FitParams,
) {
    // A closed stdout (a reader that quit) loses the lines; `println!` would panic.
    macro_rules! say {
        () => {{
            let _ = writeln!(std::io::stdout());
        }};
        ($($arg:tt)*) => {{
            let _ = writeln!(std::io::stdout(), $($arg)*);
        }};
    }
    let n = cmd.size;
    say!(
        "FoldMatch demo: a {n}×{n} sheet template ({} vertices, {} faces) and a folded, rotated,",
        n * n,
        faces.len()
    );
    say!(
        "offset scan of it ({} points, noise {}% of the width).",
        cmd.scan_points,
        cmd.noise * 100.0
    );
    say!();
    say!("                                   before        after");
    let row = |label: &str, b: f64, a: f64| say!("  {label:<28} {b:>10.5}  → {a:>10.5}");
    row(
        "RMSE to ground truth",
        before.rmse.unwrap_or(f64::NAN),
        after.rmse.unwrap_or(f64::NAN),
    );
    row(
        "f_R (RMSE / scan diagonal)",
        before.f_r.unwrap_or(f64::NAN),
        after.f_r.unwrap_or(f64::NAN),
    );
    row("f_H (Hausdorff ratio)", before.f_h, after.f_h);
    row("f_F (flipped faces)", before.f_f, after.f_f);
    row(
        "mean scan-to-fit distance",
        before.scan_to_fit_mean,
        after.scan_to_fit_mean,
    );
    say!();
    say!(
        "  fitted in {:.2} s ({} iterations, method {})",
        report.seconds.unwrap_or(f64::NAN),
        report.iterations.unwrap_or(0),
        serde_json::to_value(params.method)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default()
    );
    say!(
        "  wrote {}: template.ply, scan.ply, ground_truth.ply, fitted.ply (wrinkle-vector field), preview.png, report.json",
        cmd.output.display()
    );
}
