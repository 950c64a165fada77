use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[test]
fn cache_equals_fresh_queries_as_points_move() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let pts: Vec<[f64; 3]> = (0..3000)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    let mut queries: Vec<[f64; 3]> = (0..400)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    let index = PointIndex::new(&pts);
    let k = 12;
    let mut cache = NeighborCache::new(queries.len(), k, pts.len());
    let (mut ci, mut cd) = (vec![0; 400 * k], vec![0.0; 400 * k]);
    let (mut fi, mut fd) = (vec![0; 400 * k], vec![0.0; 400 * k]);
    let mut reused = 0;
    for step in 0..30 {
        let fresh = cache.query(&index, &queries, &mut ci, &mut cd);
        index.nearest_all(&queries, k, &mut fi, &mut fd);
        assert_eq!(ci, fi, "step {step}");
        assert_eq!(cd, fd);
        reused += queries.len() - fresh;
        for q in &mut queries {
            for c in q.iter_mut() {
                *c += 0.004 * (rng.random::<f64>() - 0.5);
            }
        }
    }
    assert!(
        reused > 5000,
        "the cache should re-use most queries, re-used {reused}"
    );
}

#[test]
fn slack_gives_approximate_neighbours_within_the_bound_and_fewer_queries() {
    // Queries descending onto a noisy plane of points from far above, as template
    // vertices do in the rigid and coarse phases.
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let pts: Vec<[f64; 3]> = (0..4000)
        .map(|_| [rng.random(), rng.random(), 0.01 * rng.random::<f64>()])
        .collect();
    let start: Vec<[f64; 3]> = (0..300)
        .map(|_| [rng.random(), rng.random(), 0.3 + 0.1 * rng.random::<f64>()])
        .collect();
    let index = PointIndex::new(&pts);
    let (k, m) = (16, start.len());
    let mut fresh_total = [0usize; 2];
    for (run, slack) in [0.0, 0.3].into_iter().enumerate() {
        let mut queries = start.clone();
        let mut cache = NeighborCache::new(m, k, pts.len());
        cache.set_slack(slack);
        let (mut ci, mut cd) = (vec![0; m * k], vec![0.0; m * k]);
        let (mut fi, mut fd) = (vec![0; m * k], vec![0.0; m * k]);
        for step in 0..40 {
            fresh_total[run] += cache.query(&index, &queries, &mut ci, &mut cd);
            index.nearest_all(&queries, k, &mut fi, &mut fd);
            for (q, query) in queries.iter().enumerate() {
                let row = q * k..(q + 1) * k;
                let true_kth = fd[row.end - 1].sqrt();
                for s in row.clone() {
                    // The distances reported are the returned points' own, nearest first.
                    let own = squared_distance(query, index.point(ci[s]));
                    assert_eq!(cd[s], own);
                    assert!(s == row.start || cd[s - 1] <= cd[s]);
                    assert!(
                        cd[s].sqrt() <= (1.0 + slack) * true_kth * (1.0 + 1e-12),
                        "step {step}, query {q}: {} beyond (1 + {slack}) × {true_kth}",
                        cd[s].sqrt()
                    );
                }
                if slack == 0.0 {
                    assert_eq!(ci[row.clone()], fi[row.clone()], "step {step}");
                }
            }
            for q in &mut queries {
                q[2] *= 0.93; // descend
                q[0] += 0.003 * (rng.random::<f64>() - 0.5);
            }
        }
    }
    assert!(
        2 * fresh_total[1] < fresh_total[0],
        "slack should spare most far re-queries: {fresh_total:?}"
    );
}

#[test]
fn reverse_nearest_equals_the_tree_and_inverts_most_queries() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    // A noisy scan of the unit square, and a template hovering over it, ever closer.
    let scan: Vec<[f64; 3]> = (0..6000)
        .map(|_| [rng.random(), rng.random(), 0.01 * rng.random::<f64>()])
        .collect();
    let side = 30;
    let index = PointIndex::new(&scan);
    // K covering a few template spacings of scan points, as ρ·N does in a fit.
    let k = 32;
    let mut reverse = ReverseNearest::new(scan.len());
    let mut got = vec![0; scan.len()];
    let mut certified = Vec::new();
    for height in [0.5, 0.05, 0.01, 0.0] {
        let template: Vec<[f64; 3]> = (0..side * side)
            .map(|i| {
                let (x, y) = ((i % side) as f64, (i / side) as f64);
                let jitter = 0.3 * (rng.random::<f64>() - 0.5);
                [
                    (x + 0.5 + jitter) / side as f64,
                    (y + 0.5) / side as f64,
                    height,
                ]
            })
            .collect();
        let mut idx = vec![0; template.len() * k];
        let mut d2 = vec![0.0; template.len() * k];
        index.nearest_all(&template, k, &mut idx, &mut d2);
        let lists = TargetNeighbours {
            indices: &idx,
            dist2: &d2,
            k,
            exact: true,
        };
        let fresh = reverse.query(&template, &scan, Some(lists), &mut got);
        let mut from_tree = vec![0; scan.len()];
        assert_eq!(
            reverse.query(&template, &scan, None, &mut from_tree),
            scan.len()
        );
        assert_eq!(from_tree, got, "height {height}: the tree alone");
        let tree = PointIndex::new(&template);
        for (j, x) in scan.iter().enumerate() {
            let (want, want_d2) = brute_force_nearest(&template, x, 1);
            assert_eq!(got[j], want[0], "height {height}, scan point {j}");
            assert_eq!(tree.nearest_one(x), (want[0], want_d2[0]));
        }
        certified.push(scan.len() - fresh);
    }
    // The exactness above covers both paths; on the scan most queries are certified.
    assert!(
        certified[0] < certified[3] && certified[3] > 3 * scan.len() / 4,
        "{certified:?}"
    );
}

#[test]
fn box_tree_equals_brute_force_near_and_far() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    // A flat patch with duplicated points (ties go to the lower index), queried on it and
    // from far above it, as the two-way attraction's scan points query the template.
    let mut pts: Vec<[f64; 3]> = (0..1500)
        .map(|_| [rng.random(), rng.random(), 0.001 * rng.random::<f64>()])
        .collect();
    pts.extend_from_within(100..140);
    let mut tree = BoxTree::default();
    for round in 0..2 {
        tree.rebuild(&pts[..pts.len() - 300 * round]);
        let live = &pts[..pts.len() - 300 * round];
        for (i, height) in (0..400).map(|i| (i, [0.0, 0.01, 0.3, 5.0][i % 4])) {
            let q = if i % 7 == 0 {
                live[i % 1200]
            } else {
                [rng.random(), rng.random(), height]
            };
            let (want, want_d2) = brute_force_nearest(live, &q, 1);
            assert_eq!(tree.nearest_one(&q), (want[0], want_d2[0]), "query {q:?}");
            // Started from any point at its distance (here: one of the 40 duplicates).
            let p = live[120];
            let known = (120, squared_distance(&p, &q));
            assert_eq!(tree.nearest_one_from(&q, known), (want[0], want_d2[0]));
            // The k nearest, in order, ties (the 40 duplicates) to the lower index, by
            // sorted insertion (30) and by gathering (150 > SORTED_LIST_MAX).
            for k in [30, 150] {
                let (near, near_d2) = brute_force_nearest(live, &q, k);
                let (mut got, mut got_d2) = (vec![0; k], vec![0.0; k]);
                tree.nearest_k_into(&q, &mut got, &mut got_d2);
                assert_eq!((&got, &got_d2), (&near, &near_d2), "query {q:?}, k {k}");
                // Within the k-th distance: the same k; within less, fewer than k.
                let (mut ball, mut ball_d2) = (vec![0; k], vec![0.0; k]);
                assert_eq!(
                    tree.nearest_k_within(&q, near_d2[k - 1], &mut ball, &mut ball_d2),
                    k
                );
                assert_eq!((&ball, &ball_d2), (&near, &near_d2), "query {q:?}, k {k}");
                let less = near_d2[k - 1] * (1.0 - 1e-9);
                let short = tree.nearest_k_within(&q, less, &mut ball, &mut ball_d2);
                let closer = near_d2.iter().filter(|&&d| d <= less).count();
                assert_eq!(short, closer);
                assert_eq!(&ball[..short], &near[..short]);
            }
        }
    }
    // One point, and points in one spot (k = all of them: ties in index order).
    tree.rebuild(&[[1.0, 2.0, 3.0]]);
    assert_eq!(tree.nearest_one(&[0.0; 3]), (0, 14.0));
    for n in [20, 150] {
        tree.rebuild(&vec![[0.5; 3]; n]);
        assert_eq!(tree.nearest_one(&[0.0; 3]).0, 0);
        let (mut all, mut all_d2) = (vec![0; n], vec![0.0; n]);
        tree.nearest_k_into(&[0.0; 3], &mut all, &mut all_d2);
        assert_eq!(all, (0..n as u32).collect::<Vec<u32>>());
        assert!(all_d2.iter().all(|&d| d == 0.75));
    }
}

#[test]
fn box_tree_refit_answers_like_brute_force_and_update_rebuilds_when_loose() {
    // A flat 40 × 40 grid, then the same points rolled up around the y axis (a fold that
    // brings x = 0 and x = 1 together), then scattered at random (the worst motion for a
    // kept grouping): a refitted tree keeps the flat grid's grouping and must still answer
    // exactly, ties to the lower index included.
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let flat: Vec<[f64; 3]> = (0..1600)
        .map(|i| [(i % 40) as f64 / 39.0, (i / 40) as f64 / 39.0, 0.0])
        .collect();
    let rolled = |t: f64| -> Vec<[f64; 3]> {
        let r = 1.0 / (t * std::f64::consts::TAU);
        flat.iter()
            .map(|p| {
                let angle = t * std::f64::consts::TAU * p[0];
                [r * angle.sin(), p[1], r * (1.0 - angle.cos())]
            })
            .collect()
    };
    let scattered: Vec<[f64; 3]> = (0..flat.len())
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    let mut refitted = BoxTree::default();
    refitted.rebuild(&flat);
    let mut updated = refitted.clone();
    let mut rebuilt = BoxTree::default();
    // Rolling bends the flat grid's leaves but keeps them compact (an isometry): refitted;
    // scattering pulls every leaf apart: rebuilt.
    for (moved, expect_loose) in [
        (rolled(0.5), false),
        (rolled(0.95), false),
        (scattered, true),
    ] {
        refitted.refit(&moved);
        let loose = refitted.looseness() > REBUILD_LOOSENESS * refitted.built_looseness;
        updated.update(&moved);
        rebuilt.rebuild(&moved);
        for i in 0..300 {
            let q = if i % 5 == 0 {
                moved[(i * 7) % moved.len()]
            } else {
                [
                    rng.random_range(-0.5..1.2),
                    rng.random(),
                    rng.random_range(-0.2..0.6),
                ]
            };
            let (want, want_d2) = brute_force_nearest(&moved, &q, 1);
            for tree in [&refitted, &updated, &rebuilt] {
                assert_eq!(tree.nearest_one(&q), (want[0], want_d2[0]), "{q:?}");
            }
        }
        assert_eq!(loose, expect_loose);
        assert!(updated.looseness() <= REBUILD_LOOSENESS * updated.built_looseness);
    }
    assert!(refitted.looseness() > 5.0 * refitted.built_looseness);
    // A translation and a uniform scale keep the looseness: no rebuild needed.
    let mut tree = BoxTree::default();
    tree.rebuild(&flat);
    let scaled: Vec<[f64; 3]> = flat
        .iter()
        .map(|p| [3.0 * p[0] + 1.0, 3.0 * p[1], 2.0])
        .collect();
    tree.refit(&scaled);
    assert!((tree.looseness() - tree.built_looseness).abs() < 1e-12 * tree.built_looseness);
}

#[test]
fn morton_order_is_a_permutation_that_keeps_neighbours_close() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let pts: Vec<[f64; 3]> = (0..4000)
        .map(|_| [rng.random(), rng.random(), 0.1 * rng.random::<f64>()])
        .collect();
    let order = morton_order(&pts);
    let mut seen = order.clone();
    seen.sort_unstable();
    assert!(seen.iter().enumerate().all(|(i, &j)| i as u32 == j));
    // Consecutive points in the order are far closer than in the given (random) order.
    let step = |o: &[u32]| {
        o.windows(2)
            .map(|w| {
                let (a, b) = (pts[w[0] as usize], pts[w[1] as usize]);
                squared_distance(&a, &b).sqrt()
            })
            .sum::<f64>()
            / (o.len() - 1) as f64
    };
    let given: Vec<u32> = (0..pts.len() as u32).collect();
    assert!(
        step(&order) * 5.0 < step(&given),
        "{} vs {}",
        step(&order),
        step(&given)
    );
    // One point, and equal points (ties by index).
    assert_eq!(morton_order(&[[0.0; 3]]), vec![0]);
    assert_eq!(morton_order(&[[1.0; 3]; 3]), vec![0, 1, 2]);
}

#[test]
fn k_clamp() {
    assert_eq!(neighborhood_size(0.002, 14_000, 8, 64), 28);
    assert_eq!(neighborhood_size(0.002, 1_000_000, 8, 64), 64);
    assert_eq!(neighborhood_size(0.002, 100, 8, 64), 8);
    assert_eq!(neighborhood_size(0.002, 5, 8, 64), 5);
}

#[test]
fn kdtree_equals_brute_force() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let pts: Vec<[f64; 3]> = (0..2000)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    let queries: Vec<[f64; 3]> = (0..300)
        .map(|_| [rng.random(), rng.random(), rng.random::<f64>() * 1.5])
        .collect();
    let index = PointIndex::new(&pts);
    let k = 17;
    let mut idx = vec![0; queries.len() * k];
    let mut d2 = vec![0.0; queries.len() * k];
    index.nearest_all(&queries, k, &mut idx, &mut d2);
    for (q, query) in queries.iter().enumerate() {
        let (bi, bd) = brute_force_nearest(&pts, query, k);
        // Random real coordinates have no ties: indices must agree exactly.
        assert_eq!(&idx[q * k..(q + 1) * k], &bi[..]);
        for s in 0..k {
            assert!((d2[q * k + s] - bd[s]).abs() < 1e-15);
        }
        assert_eq!(index.nearest_one(query).0, bi[0]);
    }
}
