from common import *
from a4_fix import reduced_gain

S = sm()
g_prod = gain(S, "euler", "closed-chain")
g_s = reduced_gain("euler")
print(
    "max diff vs scratch",
    np.abs(g_prod.stacked - g_s.stacked).max(),
    "designed rho",
    g_prod.spectral_radius,
)
for m in ("zoh", "continuous-cost"):
    g = gain(S, m, "closed-chain")
    print(
        m,
        "designed rho",
        round(g.spectral_radius, 4),
        "on coupled plant:",
        modes(Loop(g, S).matrix(), 3),
    )
# nonsingular: single support
S1 = sm(SupportState.LEFT)
a, b = gain(S1, "zoh", "full"), gain(S1, "zoh", "closed-chain")
print("single support full vs closed-chain", np.abs(a.stacked - b.stacked).max())
import time

t = time.perf_counter()
gain(S, "euler", "closed-chain")
print("design time", time.perf_counter() - t)
