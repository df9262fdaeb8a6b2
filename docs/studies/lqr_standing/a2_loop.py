from common import *

np.set_printoptions(precision=4, suppress=True, linewidth=160)
S = sm()
Sd = np.diag(np.diag(S))
w, V = np.linalg.eigh(S)
Nc = V[:, w < 1e-9]  # constrained directions (Sm null space)


def report(tag, g, true_sm, **kw):
    L = Loop(g, true_sm, **kw)
    A = L.matrix()
    ev, evec = np.linalg.eig(A)
    order = np.argsort(-np.abs(ev))
    print(
        f"{tag}: spectral radius {np.abs(ev).max():.4f}; top |eig|:",
        np.round(np.abs(ev[order[:10]]), 4),
    )
    return ev[order], evec[:, order]


g = gain(Sd)
report("diag-euler gain on its own diagonal plant (design check)", g, Sd)
report("diag-euler gain on full double-support plant", g, S)
report("diag-euler gain, lab zero dvel, full plant", g, S, zero_vel_inc=True)
g2 = gain(Sd, "zoh")
report("diag-zoh gain on full plant", g2, S)
