from common import *

np.set_printoptions(precision=3, suppress=True, linewidth=180)
S = sm()
Sd = np.diag(np.diag(S))
g = gain(Sd)
L = Loop(g, S)
A = L.matrix()
ev, evec = np.linalg.eig(A)
order = np.argsort(-np.abs(ev))
print("count |eig|>=1-1e-9:", np.sum(np.abs(ev) > 1 - 1e-9))
for i in order[:16]:
    lam = ev[i]
    f = abs(np.angle(lam)) / (2 * np.pi * DT)
    sigma = np.log(abs(lam)) / DT
    v = evec[:, i]
    u = v[6 * 12 : 7 * 12]
    tj = v[12:24]
    tm = v[:12]
    s = np.abs(u).max() or 1
    print(
        f"|l|={abs(lam):.5f} f={f:6.2f} Hz growth {sigma:+.3f} 1/s   goal shape {np.round(np.abs(u) / s, 2)}  link/goal {np.abs(tj).max() / s:.3g}"
    )
# Nyquist neighbourhood
neg = [i for i in range(len(ev)) if ev[i].real < -0.5]
print("eigs with Re<-0.5:", np.round(ev[neg], 4))
