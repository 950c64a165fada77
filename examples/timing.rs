//! Stage timing of one fit on a generated paper-sized case (≈13K template vertices, ≈14K
//! scan points): `cargo run --profile profiling --example timing -- [side] [scan] [preset]
//! [json]`, where the optional JSON object overrides the preset's parameters.
use foldmatch::fit::{fit_simple, FitParams};
use foldmatch::synthetic::{folded_sheet, SheetSpec};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let side: usize = args.get(1).map_or(115, |s| s.parse().unwrap());
    let scan: usize = args.get(2).map_or(14_400, |s| s.parse().unwrap());
    let preset = FitParams::preset(args.get(3).map_or("default", String::as_str)).unwrap();
    let params = match args.get(4) {
        Some(json) => FitParams::from_json_over(json, preset).unwrap(),
        None => preset,
    };
    let case = folded_sheet(&SheetSpec {
        nx: side,
        ny: side,
        scan_points: scan,
        noise: 0.001,
        ..Default::default()
    });
    let t = std::time::Instant::now();
    let r = fit_simple(
        &case.template_vertices,
        &case.faces,
        &case.scan,
        None,
        &params,
    )
    .unwrap();
    let total = t.elapsed().as_secs_f64();
    println!(
        "M={} N={} iterations={} threads={} total {:.3}s (setup {:.3}, iterations {:.3}, finish {:.3})",
        case.template_vertices.len(),
        case.scan.len(),
        r.iterations,
        rayon::current_num_threads(),
        total,
        r.diagnostics.wall_seconds[0],
        r.diagnostics.wall_seconds[1],
        r.diagnostics.wall_seconds[2]
    );
    println!(
        "{:#?}\nfresh k-NN queries: {} of {}; two-way tree queries: {} of {}",
        r.diagnostics.stage_seconds,
        r.diagnostics.knn_queries,
        r.iterations * case.template_vertices.len(),
        r.diagnostics.two_way_queries,
        r.iterations * case.scan.len()
    );
}
