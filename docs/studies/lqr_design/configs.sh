#!/bin/sh
# The four LQR designs of docs/humanoid.md as configuration files (in the current directory),
# each the shipped DYROS-JET configuration with the keys that make the design changed:
#   ours.toml          the shipped file: closed chain, the H54's servo cascade, zoh, R = 1e5
#   paper.toml         Kim et al. as published: one support foot's Sm (switched at mid double
#                      support), its diagonal, forward Euler, Q = 10 I, R = I, the paper's servo (4)
#   lab.toml           the lab's double-support reading: both feet's Sm, its diagonal, Euler
#   closed-chain.toml  both feet's whole Sm on the chain's motions, the paper's servo (4), Euler
# Usage: sh configs.sh   (with `hil` on the PATH, e.g. the worktree's .venv/bin)
set -e
hil config --robot dyros-jet > ours.toml
papers() {  # the paper's servo model, discretisation and weights
  sed -e 's/^servo_model = .*/servo_model = "first-order"/' \
      -e 's/^discretization = .*/discretization = "euler"/' \
      -e 's/^r_input = .*/r_input = 1.0/' \
      -e 's/^kdist_reference = .*/kdist_reference = "per-tick"/' \
      -e 's/^reference_feedforward = .*/reference_feedforward = false/' ours.toml
}
papers | sed -e 's/^sm_coupling = .*/sm_coupling = "diagonal"/' \
             -e 's/^sm_contact = .*/sm_contact = "support-foot"/' > paper.toml
papers | sed -e 's/^sm_coupling = .*/sm_coupling = "diagonal"/' > lab.toml
papers > closed-chain.toml
