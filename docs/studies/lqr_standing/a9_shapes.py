from common import *

np.set_printoptions(precision=2, suppress=True, linewidth=180)
S = sm()
w, V = np.linalg.eigh(S)
LAT = [0, 1, 5, 6, 7, 11]
SAG = [2, 3, 4, 8, 9, 10]
print("Sm eigen (nonzero) and lateral share of eigenvector:")
for i in np.argsort(-w)[:6]:
    v = V[:, i]
    print(f"  lambda {w[i]:.3f}  lateral share {np.sum(v[LAT] ** 2):.2f}  v={v}")
g = gain(np.diag(np.diag(S)))
for tag, A in (("no DOB", Loop(g, S).matrix()), ("DOB 0.2", DobLoop(g, S, 0.2).matrix())):
    ev, vec = np.linalg.eig(A)
    keep = (np.abs(ev - 1) > 1e-4) & (ev.imag >= 0) & (np.abs(ev) > 0.95)
    for i in np.flatnonzero(keep)[np.argsort(-np.abs(ev[keep]))]:
        u = vec[6 * 12 : 7 * 12, i]
        tj = vec[12:24, i]
        print(
            f"{tag}: |z| {abs(ev[i]):.4f} {abs(np.angle(ev[i])) / (2 * np.pi * DT):5.2f} Hz  goal lateral share {np.sum(np.abs(u[LAT]) ** 2) / np.sum(np.abs(u) ** 2):.2f}  link/goal {np.linalg.norm(tj) / np.linalg.norm(u):.3f}  |goal| {np.abs(u) / np.abs(u).max()}"
        )
