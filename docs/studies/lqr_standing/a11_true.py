from common import *

S = sm()
Sd = np.diag(np.diag(S))
gd = gain(Sd)
gc = gain(S, "euler", "closed-chain")
# single-joint sanity: testbed-like link I=0.376 with the true servo, diag design
for name, g in (("diagonal (product)", gd), ("closed-chain", gc)):
    print(f"{name:20s} nominal servo: {modes2(Loop(g, S).matrix())}")
    print(f"{'':20s} H54 servo    : {modes2(TrueLoop(g, S).matrix())}")
    print(f"{'':20s} H54 + DOB 0.2: {modes2(TrueLoop(g, S, kdist=0.2).matrix())}")
