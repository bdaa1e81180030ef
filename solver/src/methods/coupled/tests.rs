use super::*;

fn case(n: usize, field: &str) -> Case {
    Case::parse(serde_json::json!({
        "method": "coupled_1d", "dim": 1, "n": n, "eps": 0.065,
        "kernel": "inverse_distance", "patch": field
    }))
    .unwrap()
}

/// Without `local_domain` the local problem lies on the seed's [0.75, 1.75]: the same
/// problem as one that writes it, overlapping Ω_n on Ω_b = (0.75, 1).
#[test]
fn the_default_layout_is_the_papers() {
    let implicit = case(16, "quadratic");
    let explicit = Case {
        local_domain: Some([0.75, 1.75]),
        ..implicit.clone()
    };
    let built = Coupled::new(&implicit).unwrap();
    assert_eq!(built.overlap, Coupled::new(&explicit).unwrap().overlap);
    let length: f64 = built.overlap.iter().map(|(_, w)| w).sum();
    assert!((length - 0.25).abs() < 1e-12, "|Ω_b| = {length}");
    let inside = built.overlap.iter().all(|&(x, _)| 0.75 < x && x < 1.0);
    assert!(inside, "Gauss points of Ω_b outside (0.75, 1)");
    let case =
        Case::parse(serde_json::json!({"method": "coupled_1d", "dim": 1, "n": 8, "eps": 0.065}))
            .unwrap();
    assert!(validate(&case).is_ok());
    assert_eq!(case.patch(), crate::case::PatchField::Linear);
}

/// J measured directly on the states, not through Ψ: no control vector does better than the
/// optimum, neither the exact solution's values nor a step along any control.
#[test]
fn the_optimum_minimises_the_mismatch() {
    for field in ["quadratic", "quartic"] {
        for n in [8, 16, 64] {
            let problem = Coupled::new(&case(n, field)).unwrap();
            let theta = problem.optimum().unwrap().theta;
            let best = problem.mismatch(&problem.states(&theta));
            let exact = case(n, field).patch.unwrap();
            let u = |x: f64| exact.value(x);
            let mut exact_controls: Vec<f64> = problem
                .nonlocal
                .control_nodes
                .iter()
                .map(|&x| u(x))
                .collect();
            exact_controls.push(u(0.75));
            let at_exact = problem.mismatch(&problem.states(&exact_controls));
            assert!(
                best <= at_exact,
                "{field} n={n}: {best:e} > {at_exact:e} at u's values"
            );
            if n > 16 {
                continue; // every direction resolved (no smoothing pull) only on coarse meshes
            }
            for j in 0..theta.len() {
                for step in [-1e-4, 1e-4] {
                    let mut moved = theta.clone();
                    moved[j] += step;
                    let there = problem.mismatch(&problem.states(&moved));
                    assert!(
                        there >= best * (1.0 - 1e-12),
                        "{field} n={n} control {j}: {there:e} < {best:e}"
                    );
                }
            }
        }
    }
}

/// The sizes `validate` predicts are the meshes `Coupled::new` builds.
#[test]
fn the_predicted_sizes_are_the_meshes_built() {
    for (n, eps, a, b) in [
        (8, 0.065, 0.75, 1.75),
        (64, 0.065, 0.75, 1.75),
        (128, 0.065, 0.8, 1.3),
        (40, 0.3, 0.5, 2.0),
        (33, 0.1, 0.97, 1.5),
    ] {
        let case = Case::parse(serde_json::json!({
            "method": "coupled_1d", "dim": 1, "n": n, "eps": eps, "local_domain": [a, b]
        }))
        .unwrap();
        let sizes = Sizes::of_case(&case);
        let problem = Coupled::new(&case).unwrap();
        let context = format!("n={n} ε={eps} [{a}, {b}]");
        assert_eq!(
            sizes.nonlocal_nodes,
            problem.nonlocal.mesh.len() as f64,
            "{context}"
        );
        assert_eq!(
            sizes.local_nodes,
            problem.local.mesh.len() as f64,
            "{context}"
        );
        assert_eq!(
            sizes.controls(),
            problem.nonlocal.control_nodes.len() as f64,
            "{context}"
        );
        // Two Gauss points per piece; a node within rounding of a or 1 may count or not.
        let points = problem.overlap.len() as f64;
        let (fewest, most) = sizes.overlap_breaks;
        assert!(
            2.0 * fewest <= points && points <= 2.0 * (most + 2.0),
            "{context}: {points} Gauss points, predicted {fewest} … {most} breaks"
        );
    }
}

/// An overlap thinner than an element is refused by `validate`, and `least_squares`
/// refuses too few rows instead of letting faer assert.
#[test]
fn an_overlap_too_thin_for_its_controls_is_refused() {
    let case = Case::parse(serde_json::json!({
        "method": "coupled_1d", "dim": 1, "n": 64, "eps": 0.065, "local_domain": [0.99, 1.75]
    }))
    .unwrap();
    let refusal = validate(&case).unwrap_err();
    assert_eq!(refusal.field, "local_domain", "{refusal}");
    let psi = Mat::from_fn(2, 4, |i, j| (i + j) as f64 + 1.0);
    let d0 = Mat::from_fn(2, 1, |i, _| i as f64);
    let smoothing = second_differences(&[1.0, 1.01, 1.02], 0.01, 4);
    let refusal = least_squares(&psi, &d0, &smoothing).err().unwrap();
    assert_eq!(refusal.field, "local_domain", "{refusal}");
}

/// The set-up time model refuses what would run for days and admits the local mesh's cap,
/// linear since `BandMatrix::block` reads only the band.
#[test]
fn the_set_up_time_model_refuses_days_and_admits_the_element_cap() {
    let case = |n: usize, b: f64| {
        Case::parse(serde_json::json!({
            "method": "coupled_1d", "dim": 1, "n": n, "eps": 0.065, "local_domain": [0.75, b]
        }))
        .unwrap()
    };
    let seconds = |case: &Case| Sizes::of_case(case).setup_seconds();
    assert!(seconds(&case(128, 1.75)) < 0.1);
    let at_cap = case(10, 0.75 + 0.999e7);
    assert!(validate(&at_cap).is_ok(), "{:?}", validate(&at_cap));
    assert!(seconds(&at_cap) < MAX_SETUP_S);
    let refusal = validate(&case(1_000_000, 1.75)).unwrap_err();
    assert_eq!(refusal.field, "n", "{refusal}");
}

#[test]
fn second_differences_vanish_on_linear_data_over_uneven_nodes() {
    let nodes = [1.0, 1.0078125, 1.015625, 1.065];
    let d = second_differences(&nodes, 0.0078125, 5);
    let linear = Mat::from_fn(5, 1, |j, _| if j < 4 { 3.0 * nodes[j] - 1.0 } else { 7.0 });
    assert!((&d * &linear).norm_l2() < 1e-15);
    let quadratic = Mat::from_fn(5, 1, |j, _| if j < 4 { nodes[j] * nodes[j] } else { 0.0 });
    let expected = 2.0 * 0.0078125f64.powi(2);
    for i in 0..2 {
        assert!(((&d * &quadratic)[(i, 0)] - expected).abs() < 1e-14);
    }
}
