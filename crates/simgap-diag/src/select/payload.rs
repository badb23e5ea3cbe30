//! The payload's centre of mass, searched jointly with the other selected terms: a linear
//! first guess, then Nelder–Mead on the fit residual ([`Context::payload_search`]).

use nalgebra::{DMatrix, DVector};
use simgap_core::PARAMS_PER_LINK;

use super::context::{Context, PayloadBasis, PAYLOAD_BLOCK};
use super::residual::screen_fit;
use crate::lsq::{grams, Grams};
use crate::vocabulary::{largest_command, payload_basis_rows, payload_mass_bound, point_mass_parameters, Column, Term, TermDesign};

impl Context<'_> {
    /// The payload's centre of mass: a linear first guess (mass and first moment of the last
    /// link), then Nelder–Mead on the cross-validation-free fit residual of `rest` + payload.
    pub(super) fn payload_search(&self, resid: &Column, rest: &[TermDesign]) -> Term {
        let p = &self.problem;
        let (th, _) = screen_fit(p, &crate::vocabulary::payload_linear_design(self.data), resid);
        let c0 = if th.len() == 4 && th[0].abs() > 1e-9 { [th[1] / th[0], th[2] / th[0], th[3] / th[0]] } else { [0.0; 3] };
        // the centre of mass stays within reach of the last link
        let reach = self.prior.reach.last().copied().unwrap_or(f64::INFINITY);
        let within = |c: &[f64; 3]| -> [f64; 3] {
            let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if n > reach {
                c.map(|x| x * reach / n)
            } else {
                *c
            }
        };
        let c0 = within(&c0.map(|x| if x.is_finite() { x } else { 0.0 }));
        // more starts: the last link's first moment is identified better than its mass, whose
        // linear estimate can even come out negative and send h/m to the opposite side of the
        // link; its direction at a quarter, half and the whole of the reach, and the link's origin
        let mut starts = Vec::new();
        if th.len() == 4 {
            let h = [th[1], th[2], th[3]];
            let norm = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
            let r = if reach.is_finite() && reach > 0.0 { reach } else { 0.2 };
            if norm > 0.0 && norm.is_finite() {
                starts.extend([0.25, 0.5, 1.0].map(|f| within(&h.map(|x| x / norm * f * r))));
            }
        }
        starts.push([0.0; 3]);
        let max_mass = self.max_payload();
        // the Grams of `rest` and of the ten basis columns, once: the payload's inner products
        // are then linear and quadratic forms in π(c) (equal to the column's own up to rounding)
        let basis = self.payload.get_or_init(|| {
            let rows = payload_basis_rows(self.data);
            let cols: Vec<Column> = (0..PARAMS_PER_LINK).map(|i| Column::new(None, rows.iter().skip(i).step_by(PARAMS_PER_LINK).copied().collect())).collect();
            let nonzero: Vec<usize> = (0..PARAMS_PER_LINK).filter(|&i| cols[i].values.iter().any(|v| *v != 0.0)).collect();
            let mut compact: Vec<(f64, Vec<f64>)> = rows
                .chunks_exact(PARAMS_PER_LINK)
                .map(|r| {
                    let v: Vec<f64> = nonzero.iter().map(|&i| r[i]).collect();
                    (v.iter().map(|x| x * x).sum::<f64>().sqrt(), v)
                })
                .collect();
            compact.sort_by(|a, b| b.0.total_cmp(&a.0));
            let norms = compact.iter().map(|r| r.0).collect();
            let rows: Vec<f64> = compact.into_iter().flat_map(|r| r.1).collect();
            // (no entry left: no rows, no blocks; `chunks` asks for a positive size)
            let nz = nonzero.len().max(1);
            let block_bounds =
                rows.chunks(nz * PAYLOAD_BLOCK).flat_map(|block| (0..nz).map(move |i| block.iter().skip(i).step_by(nz).fold(0.0f64, |m, v| m.max(v.abs())))).collect();
            PayloadBasis { rows, norms, nonzero, block_bounds, design: TermDesign::free(cols), tau_max: largest_command(self.data) }
        });
        let mut refs: Vec<&TermDesign> = rest.iter().collect();
        refs.push(&basis.design);
        let full = grams(p, &refs);
        let k = full.k - PARAMS_PER_LINK;
        let (mut g_full, mut c_full, mut s) = (DMatrix::zeros(full.k, full.k), DVector::zeros(full.k), 0.0);
        for b in 0..full.g.len() {
            g_full += &full.g[b];
            c_full += &full.c[b];
            s += full.s[b];
        }
        let (mut lo, mut hi) = (full.lo[..k].to_vec(), full.hi[..k].to_vec());
        lo.push(0.0);
        hi.push(f64::INFINITY);
        let mut solver = Grams { k: k + 1, g: Vec::new(), c: Vec::new(), s: Vec::new(), dof: p.dof, lo, hi, inertial: full.inertial.clone() };
        let mut g = DMatrix::zeros(k + 1, k + 1);
        g.view_mut((0, 0), (k, k)).copy_from(&g_full.view((0, 0), (k, k)));
        let mut c = DVector::zeros(k + 1);
        c.rows_mut(0, k).copy_from(&c_full.rows(0, k));
        let mut sse = |com: &[f64; 3]| -> f64 {
            let pi = point_mass_parameters(within(com));
            // the mass bound from the column's largest entry, as the payload's design states it
            // (the entries left out are zero: the same sums); |row·π| <= ‖row‖ ‖π‖, so once
            // that bound falls below the largest entry found, no later row can exceed it
            // (a block whose entries' bounds cannot exceed the largest found is skipped)
            let nz = basis.nonzero.len();
            let (mut pi_nz, mut pi_abs) = ([0.0; PARAMS_PER_LINK], [0.0; PARAMS_PER_LINK]);
            for (a, &i) in basis.nonzero.iter().enumerate() {
                pi_nz[a] = pi[i];
                pi_abs[a] = pi[i].abs();
            }
            let (pi_nz, pi_abs) = (&pi_nz[..nz], &pi_abs[..nz]);
            let pi_norm = pi_nz.iter().map(|x| x * x).sum::<f64>().sqrt();
            let mut col_max = 0.0f64;
            if nz > 0 {
                let blocks = basis.rows.chunks(nz * PAYLOAD_BLOCK).zip(basis.norms.chunks(PAYLOAD_BLOCK)).zip(basis.block_bounds.chunks_exact(nz));
                'rows: for ((block, norms), bound) in blocks {
                    if bound.iter().zip(pi_abs).map(|(a, b)| a * b).sum::<f64>() * (1.0 + 1e-9) < col_max {
                        continue;
                    }
                    for (row, norm) in block.chunks_exact(nz).zip(norms) {
                        if norm * pi_norm * (1.0 + 1e-9) < col_max {
                            break 'rows;
                        }
                        col_max = col_max.max(row.iter().zip(pi_nz).map(|(a, b)| a * b).sum::<f64>().abs());
                    }
                }
            }
            solver.hi[k] = payload_mass_bound(col_max, basis.tau_max, max_mass);
            // the payload column's inner products: Y π against the rest, itself and the residual
            for a in 0..k {
                let v: f64 = (0..PARAMS_PER_LINK).map(|i| pi[i] * g_full[(a, k + i)]).sum();
                g[(a, k)] = v;
                g[(k, a)] = v;
            }
            g[(k, k)] = (0..PARAMS_PER_LINK).map(|i| pi[i] * (0..PARAMS_PER_LINK).map(|l| pi[l] * g_full[(k + i, k + l)]).sum::<f64>()).sum();
            c[k] = (0..PARAMS_PER_LINK).map(|i| pi[i] * c_full[k + i]).sum();
            let t = solver.solve(&g, &c);
            s - 2.0 * t.dot(&c) + t.dot(&(&g * &t))
        };
        // the best of the searches from h/m and from every other start
        let mut search = |start: [f64; 3]| {
            let com = within(&nelder_mead(&mut sse, start, 0.02, 60));
            (com, sse(&com))
        };
        let mut best = search(c0);
        for start in starts {
            let found = search(start);
            if found.1 < best.1 {
                best = found;
            }
        }
        Term::Payload { com: best.0, max_mass }
    }

    /// The largest plausible payload [kg]: twice the mass of the chain's links in the URDF.
    pub(super) fn max_payload(&self) -> f64 {
        let total: f64 = self.prior.nominal.iter().step_by(simgap_core::PARAMS_PER_LINK).sum();
        if total > 0.0 {
            2.0 * total
        } else {
            f64::INFINITY
        }
    }
}

/// Minimises `f` over 3-vectors by Nelder–Mead from `x0` with initial step `step`.
fn nelder_mead(mut f: impl FnMut(&[f64; 3]) -> f64, x0: [f64; 3], step: f64, iters: usize) -> [f64; 3] {
    let mut pts: Vec<([f64; 3], f64)> = (0..4)
        .map(|i| {
            let mut x = x0;
            if i > 0 {
                x[i - 1] += step;
            }
            (x, f(&x))
        })
        .collect();
    for _ in 0..iters {
        pts.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut centroid = [0.0; 3];
        for p in &pts[..3] {
            for k in 0..3 {
                centroid[k] += p.0[k] / 3.0;
            }
        }
        let along = |t: f64| -> [f64; 3] { std::array::from_fn(|k| centroid[k] + t * (pts[3].0[k] - centroid[k])) };
        let xr = along(-1.0);
        let fr = f(&xr);
        if fr < pts[0].1 {
            let xe = along(-2.0);
            let fe = f(&xe);
            pts[3] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < pts[2].1 {
            pts[3] = (xr, fr);
        } else {
            let xc = along(0.5);
            let fc = f(&xc);
            if fc < pts[3].1 {
                pts[3] = (xc, fc);
            } else {
                let best = pts[0].0;
                for p in pts.iter_mut().skip(1) {
                    p.0 = std::array::from_fn(|k| best[k] + 0.5 * (p.0[k] - best[k]));
                    p.1 = f(&p.0);
                }
            }
        }
    }
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    pts[0].0
}
