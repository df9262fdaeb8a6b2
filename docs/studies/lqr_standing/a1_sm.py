from common import *

np.set_printoptions(precision=3, suppress=True, linewidth=160)
S = sm()
w, V = np.linalg.eigh(S)
print("Sm full double eigenvalues", w)
print("diag", np.diag(S))
for sup in (SupportState.LEFT, SupportState.RIGHT):
    print(sup, "diag", np.diag(sm(sup)))
# free floating (no contact) as the lab when not walking
import pinocchio as pin

q = lm.configuration(POSTURE)
M = pin.crba(lm.model, lm.data, q)
M = 0.5 * (M + M.T)
Minv = np.linalg.inv(M)[np.ix_(lm.leg_v_index, lm.leg_v_index)]
print("no contact diag", np.diag(Minv))
print(
    "1/diag(M_legs) (fixed base, other joints locked)",
    1 / np.diag(M[np.ix_(lm.leg_v_index, lm.leg_v_index)]),
)
g = gain(S)
print("Ke diag", np.diag(g.error_gain))
