from common import *
from controller.lqr import TrackingGain

S = sm()
gc = gain(S, "euler", "closed-chain")
gd = gain(np.diag(np.diag(S)))


def scaled(g, f):
    return TrackingGain(g.error_gain * f, g.state_increment_gain * f, DT, float("nan"))


for name, g in (("closed-chain", gc), ("diagonal", gd)):
    for f in (0.5, 0.8, 1.0, 1.25, 1.5):
        print(name, "gain x", f, "H54 rigid contact:", modes2(TrueLoop(scaled(g, f), S).matrix()))
# servo slower than the model: Kpp 7.2 (the testbed's first-order fit of the emulated servo)
print(
    "closed-chain, H54 with Kpp 7.2:",
    modes2(TrueLoop(gc, S, kpp=np.where(PARAMS.servo_gain_per_s > 10, 13.0, 7.2)).matrix()),
)
print("closed-chain, H54 with kv halved:", modes2(TrueLoop(gc, S, kv=39.0).matrix()))
