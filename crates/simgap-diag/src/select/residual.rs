//! The torque residual as the selection reads it: one design fitted against it ([`screen_fit`])
//! and the best of candidate terms by that fit ([`screen_best`]), what a fitted set leaves of it
//! ([`residual_after`]) and the torque a fitted term explains ([`term_torque_rms`]).

use nalgebra::{DMatrix, DVector};
use std::sync::Arc;

use super::context::Context;
use crate::lsq::{block_squares, grams_against_known, Problem};
use crate::vocabulary::{Column, Term, TermDesign};

/// Least-squares fit of one design against a residual column: (θ, weighted SSE).
pub(super) fn screen_fit(p: &Problem, d: &TermDesign, resid: &Column) -> (DVector<f64>, f64) {
    screen_fit_known(p, d, resid, None)
}

/// [`screen_fit`] with `resid·resid` per block known (see [`grams_against_known`]).
fn screen_fit_known(p: &Problem, d: &TermDesign, resid: &Column, resid_squares: Option<&[f64]>) -> (DVector<f64>, f64) {
    let gr = grams_against_known(p, resid, &[d], resid_squares);
    let (mut g, mut c, mut s) = (DMatrix::zeros(gr.k, gr.k), DVector::zeros(gr.k), 0.0);
    for b in 0..gr.g.len() {
        g += &gr.g[b];
        c += &gr.c[b];
        s += gr.s[b];
    }
    let th = gr.solve(&g, &c);
    let sse = s - 2.0 * th.dot(&c) + th.dot(&(&g * &th));
    (th, sse)
}

pub(super) fn screen_best(ctx: &Context<'_>, cands: &[Term], resid: &Column) -> (Term, f64) {
    let p = &ctx.problem;
    let mut best = (cands[0].clone(), f64::INFINITY);
    // resid·resid once for the members without a fixed offset
    let mut squares: Option<Vec<f64>> = None;
    for t in cands {
        let d = ctx.design_shared(t);
        if d.offset.is_none() && squares.is_none() {
            squares = Some(block_squares(p, resid));
        }
        let (th, sse) = screen_fit_known(p, &d, resid, squares.as_deref());
        // a Stribeck member without a static level above the Coulomb level is Coulomb friction
        if matches!(t, Term::Stribeck { .. }) && !(th[1] > 0.0) {
            continue;
        }
        if sse < best.1 {
            best = (t.clone(), sse);
        }
    }
    best
}

/// The residual left by a fitted set of terms, as a global column.
pub(crate) fn residual_after(p: &Problem, designs: &[TermDesign], theta: &DVector<f64>) -> Column {
    let dof = p.dof;
    let mut r = p.y.clone();
    let values = Arc::make_mut(&mut r.values);
    let mut c = 0;
    for d in designs {
        if let Some(off) = &d.offset {
            for s in 0..p.samples {
                for j in 0..dof {
                    values[s * dof + j] -= off.at(s, j, dof);
                }
            }
        }
        for col in &d.cols {
            let th = theta[c];
            c += 1;
            for s in 0..p.samples {
                for j in 0..dof {
                    values[s * dof + j] -= th * col.at(s, j, dof);
                }
            }
        }
    }
    r
}

/// RMS torque a fitted term explains on each joint.
pub(crate) fn term_torque_rms(p: &Problem, d: &TermDesign, theta: &[f64]) -> Vec<f64> {
    let dof = p.dof;
    let mut acc = vec![0.0; dof];
    for s in 0..p.samples {
        for (j, a) in acc.iter_mut().enumerate() {
            let mut v = d.offset.as_ref().map_or(0.0, |o| o.at(s, j, dof));
            for (col, th) in d.cols.iter().zip(theta) {
                v += th * col.at(s, j, dof);
            }
            *a += v * v;
        }
    }
    acc.iter().map(|a| (a / p.samples.max(1) as f64).sqrt()).collect()
}
