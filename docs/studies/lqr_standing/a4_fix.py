from common import *
from controller.lqr import augmented_discrete, discrete_lqr, TrackingGain

np.set_printoptions(precision=3, suppress=True, linewidth=180)
S = sm()
Sd = np.diag(np.diag(S))
w, V = np.linalg.eigh(S)
tol = 1e-9 * w.max()
Vr = V[:, w > tol]
r = Vr.shape[1]
P = Vr @ Vr.T
print("rank", r)


def radius(A):
    return np.abs(np.linalg.eigvals(A)).max()


def reduced_gain(method="euler"):
    n = 12
    K = np.diag(PARAMS.stiffness_nm_per_rad)
    D = np.diag(PARAMS.damping_nms_per_rad)
    Kp = np.diag(PARAMS.servo_gain_per_s)
    Lam = Vr.T @ S @ Vr  # diag of nonzero eigenvalues
    # x_r = [th_m (n); xi (r); dxi (r)], th_j = Vr xi
    A = np.zeros((n + 2 * r, n + 2 * r))
    B = np.zeros((n + 2 * r, n))
    A[:n, :n] = -Kp
    B[:n] = Kp
    A[n : n + r, n + r :] = np.eye(r)
    A[n + r :, :n] = Lam @ Vr.T @ (K - D @ Kp)
    A[n + r :, n : n + r] = -Lam @ Vr.T @ K @ Vr
    A[n + r :, n + r :] = -Lam @ Vr.T @ D @ Vr
    B[n + r :] = Lam @ Vr.T @ D @ Kp
    C = np.hstack([np.zeros((r, n)), np.eye(r), np.zeros((r, r))])
    if method == "euler":
        Ad, Bd = np.eye(n + 2 * r) + A * DT, B * DT
    else:
        import scipy.linalg

        M = np.zeros((n + 2 * r + n,) * 2)
        M[: n + 2 * r, : n + 2 * r] = A
        M[: n + 2 * r, n + 2 * r :] = B
        E = scipy.linalg.expm(M * DT)
        Ad, Bd = E[: n + 2 * r, : n + 2 * r], E[: n + 2 * r, n + 2 * r :]
    Aa, Ba = augmented_discrete(Ad, Bd, C)
    Q = np.diag(np.r_[np.full(r, 10.0), np.ones(n + 2 * r)])
    R = np.eye(n)
    sol = discrete_lqr(Aa, Ba, Q, R)
    Kg = sol.gain
    ke = Kg[:, :r] @ Vr.T
    km = Kg[:, r : r + n]
    kj = Kg[:, r + n : r + n + r] @ Vr.T
    kv = Kg[:, r + n + r :] @ Vr.T
    return TrackingGain(ke, np.hstack([km, kj, kv]), DT, radius(Aa - Ba @ Kg))


gd = gain(Sd)
for tag, g, proj in [
    ("diag (lab)", gd, None),
    ("diag + projected error", gd, P),
    ("reduced euler", reduced_gain("euler"), None),
    ("reduced zoh", reduced_gain("zoh"), None),
]:
    for zero in (False, True):
        L = Loop(g, S, zero_vel_inc=zero, error_projector=proj)
        ev = np.linalg.eigvals(L.matrix())
        big = ev[np.abs(ev) > 1 - 1e-6]
        # exclude exact 1's (constrained, uncontrollable: link cannot move)
        osc = ev[(np.abs(ev) > 0.999) & (np.abs(ev.imag) > 1e-6)]
        print(
            f"{tag:24s} zero dvel={zero!s:5s} radius {np.abs(ev).max():.5f}  #|l|>=1: {big.size}  "
            f"largest non-unit: {np.sort(np.abs(ev[np.abs(ev - 1) > 1e-4]))[-1]:.5f}"
        )
gr = reduced_gain("euler")
print("designed radius reduced euler", gr.spectral_radius)
print("Ke reduced diag", np.diag(gr.error_gain))
