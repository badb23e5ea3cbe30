# Split the DFKI design A.0 sys-id record into two time windows (fit / held-out), in simgap's
# generic CSV convention, with the reference q_d, qd_d of the excitation trajectory interpolated
# at the log's time stamps (the record itself carries no reference).
import csv, gzip, sys, bisect
D = sys.argv[1]; out = sys.argv[2]
rec = D + '/experiment_records/design_A.0/20220812/sys_id/20220812-061157-PM_measured.csv.gz'
ref = D + '/system_identification/excitation_trajectories/trajectory-pos-20.csv.gz'
def load(p):
    with gzip.open(p, 'rt') as f:
        r = csv.reader(f); h = next(r); return h, [[float(x) for x in row] for row in r]
h, a = load(rec); hr, b = load(ref)
tr = [x[0] for x in b]
def interp(t, col):
    i = min(max(bisect.bisect_right(tr, t) - 1, 0), len(tr) - 2)
    w = (t - tr[i]) / (tr[i + 1] - tr[i]); w = min(max(w, 0.0), 1.0)
    return b[i][col] * (1 - w) + b[i + 1][col] * w
rows = []
for x in a:
    t = x[0]
    qd = [interp(t, 1), interp(t, 2)]; vd = [interp(t, 3), interp(t, 4)]
    rows.append([t, x[1], x[2], x[3], x[4], x[5], x[6], qd[0], qd[1], vd[0], vd[1]])
# PD law check: least squares tau_i = kp e_i + kv ed_i
for j in range(2):
    e = [r[7 + j] - r[1 + j] for r in rows]; ed = [r[9 + j] - r[3 + j] for r in rows]; tau = [r[5 + j] for r in rows]
    see = sum(v * v for v in e); sdd = sum(v * v for v in ed); sed = sum(u * v for u, v in zip(e, ed))
    set_ = sum(u * v for u, v in zip(e, tau)); sdt = sum(u * v for u, v in zip(ed, tau))
    det = see * sdd - sed * sed; kp = (set_ * sdd - sdt * sed) / det; kv = (sdt * see - set_ * sed) / det
    res = [t_ - (20 * u + 0.6 * v) for t_, u, v in zip(tau, e, ed)]
    print(f'joint {j+1}: least-squares kp = {kp:.3f} kv = {kv:.3f}; rms(tau - (20 e + 0.6 ed)) = {(sum(r*r for r in res)/len(res))**0.5:.4f} N·m, rms tau = {(sum(t*t for t in tau)/len(tau))**0.5:.4f}')
hdr = ['time', 'q_Joint1', 'q_Joint2', 'qd_Joint1', 'qd_Joint2', 'tau_Joint1', 'tau_Joint2', 'q_ref_Joint1', 'q_ref_Joint2', 'qd_ref_Joint1', 'qd_ref_Joint2']
T = rows[-1][0]; half = T / 2
for name, sel in [('a0_first_half', [r for r in rows if r[0] < half]), ('a0_second_half', [r for r in rows if r[0] >= half])]:
    with open(f'{out}/{name}.csv', 'w', newline='') as f:
        w = csv.writer(f); w.writerow(hdr); w.writerows(sel)
    print(name, len(sel), 'samples', f'{sel[0][0]:.3f}–{sel[-1][0]:.3f} s')
