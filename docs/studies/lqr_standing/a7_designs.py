from common import *
from a4_fix import reduced_gain, P

np.set_printoptions(precision=3, suppress=True, linewidth=180)
S = sm()
designs = {
    "diag double (product)": gain(np.diag(np.diag(S))),
    "diag left single (lab walking)": gain(np.diag(np.diag(sm(SupportState.LEFT)))),
}
import pinocchio as pin

q = lm.configuration(POSTURE)
M = pin.crba(lm.model, lm.data, q)
M = 0.5 * (M + M.T)
Minv = np.linalg.inv(M)[np.ix_(lm.leg_v_index, lm.leg_v_index)]
designs["diag no contact (lab standing)"] = gain(np.diag(np.diag(Minv)))
designs["reduced (projected error)"] = reduced_gain("euler")
for name, g in designs.items():
    print(f"{name:32s} designed rho {g.spectral_radius:.4f}")
    print("    no DOB      :", modes(Loop(g, S).matrix()))
    print("    DOB Kd 0.2  :", modes(DobLoop(g, S, 0.2).matrix()))
    print("    DOB Kd 1.0  :", modes(DobLoop(g, S, 1.0).matrix()))
