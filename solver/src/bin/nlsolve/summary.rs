//! The one line a run says on standard error: the case as people name it, what it took and
//! what it measured.

use serde_json::Value;
use solver::case::Method;
use solver::output::record::Record;

/// The name a value has in the JSON case and record (`linear`, `neighbour_list`, `ok`).
pub(crate) fn label<T: serde::Serialize>(value: &T) -> String {
    match serde_json::to_value(value) {
        Ok(Value::String(name)) => name,
        _ => String::from("?"),
    }
}

pub(crate) fn summary(record: &Record) -> String {
    let case = &record.case;
    let errors = match (record.error_l2_norm, record.error_max) {
        (Some(l2), Some(max)) => format!("; error L2 norm {l2:.3e}, max {max:.3e}"),
        _ => String::new(),
    };
    let resolved = &record.resolved;
    let method = match (case.method, resolved.m, resolved.eps) {
        (Method::Pse, _, Some(eps)) => format!("pse ε={eps:.4} (ε/h {:.3})", eps / resolved.h),
        (_, Some(m), _) => format!(
            "m={m} {} {} {}",
            label(&case.kernel),
            label(&case.quadrature),
            resolved
                .backend
                .map_or_else(|| label(&case.backend), |b| label(&b))
        ),
        _ => label(&case.method),
    };
    if let Some(patch) = &record.patch {
        return format!(
            "nlsolve: patch test n={} {} {} field, {}, ε from {:.4} to {:.4}: max |L_h u − k u''| = {:.3e} over {} bonds; dt_stable {:.3e}; status {}",
            case.n,
            label(&case.kernel),
            label(&case.patch()),
            label(&case.formulation()),
            patch.eps_min,
            resolved.eps.unwrap_or(f64::NAN),
            patch.ghost_force,
            resolved.bonds,
            resolved.dt_stable,
            label(&record.status),
        );
    }
    if let Some(coupled) = &record.coupling {
        let optimum = match (coupled.mismatch, coupled.gradient) {
            (Some(mismatch), Some(gradient)) => format!(
                "overlap mismatch {mismatch:.3e}, ‖∇J‖/‖∇J(0)‖ {gradient:.1e} over {} controls",
                coupled.controls_nonlocal.len() + 1
            ),
            _ => "no interface: the horizon shrinks to h over the overlap".into(),
        };
        return format!(
            "nlsolve: coupled_1d ({}) n={} ε={} {} {} field, local domain [{}, {}]: e(u_n) {:.3e}, e(u_l) {:.3e}, {optimum}; status {}",
            label(&case.coupling()),
            case.n,
            resolved.eps.unwrap_or(f64::NAN),
            label(&case.kernel),
            label(&case.patch()),
            coupled.local_domain[0],
            coupled.local_domain[1],
            coupled.error_nonlocal,
            coupled.error_local,
            label(&record.status),
        );
    }
    if let Some(iterations) = record.steady.iterations {
        let solver = match case.subdomains {
            Some(p) => format!(
                "feti {p}×{p} ({}) with {} multipliers",
                label(&case.preconditioner()),
                record.steady.multipliers.unwrap_or(0)
            ),
            None => "cg".into(),
        };
        return format!(
            "nlsolve: steady n={} {method}, {solver}, {} rank(s) × {} thread(s): {iterations} iterations in {:.3e} s (setup {:.3e} s), relative residual {:.2e}{errors}; status {} {}",
            case.n,
            case.ranks,
            case.threads,
            record.solve_s,
            record.setup_s,
            record.steady.relative_residual.unwrap_or(f64::NAN),
            label(&record.status),
            record.message,
        );
    }
    let solves = match record.implicit.solve_iterations_mean {
        Some(mean) => format!(
            ", {mean:.1} CG iterations per step (max {})",
            record.implicit.solve_iterations_max.unwrap_or(0)
        ),
        None => String::new(),
    };
    format!(
        "nlsolve: {}D n={} {method} {}, {} rank(s) × {} thread(s): {} steps of dt={:.3e} (dt/dt_stable {:.3}){solves} in {:.3e} s, {:.3e} s/step{errors}; status {} {}",
        case.dim,
        case.n,
        label(&case.integrator),
        case.ranks,
        case.threads,
        record.steps_done,
        record.resolved.dt,
        record.resolved.dt / record.resolved.dt_stable,
        record.solve_s,
        record.step_s,
        label(&record.status),
        record.message,
    )
}
