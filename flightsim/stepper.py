"""One physics step of V vehicles (controller + motor clipping + RK4 of RotorPy's dynamics),
compiled once into a CasADi SX function and evaluated through CasADi's zero-copy buffers.

Why: RotorPy's own ``Multirotor.step`` (scipy ``solve_ivp``) costs about 1 ms per vehicle and
step, i.e. 1x real time for two vehicles at 500 Hz; numpy on (V, 3) arrays is dominated by per-call
overhead. The same scalar equations (:func:`proxplan.flightsim.dynamics.state_derivative`,
:func:`proxplan.flightsim.control.se3_control`) compiled into one CasADi function take a few tens of
microseconds per step for all vehicles.

Per step: the controller runs on the state at the step start (zero-order hold, as RotorPy's
simulator does): per vehicle either the Crazyflie firmware's Mellinger law
(:mod:`proxplan.flightsim.mellinger`, motor thrusts capped by the firmware's rule, its memory carried
in ``ctrl_mem``) or RotorPy's SE(3) law (``None`` in ``controllers``); the rotor-speed commands
sqrt(f / k_eta) are clipped to the motor range, the external force
(world frame) and torque (world axes, rotated into the body frame at the step start) are held, and
one classic RK4 step of ``dt_s`` integrates the state; afterwards the quaternion is renormalised
and the rotor speeds are clipped to the motor range (both as RotorPy's ``step``).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from proxplan.flightsim.control import ControllerConstants, se3_control
from proxplan.flightsim.dynamics import STATE_SIZE, VehicleConstants, mat_t_vec, rotation, state_derivative
from proxplan.flightsim.mellinger import CONTROLLER_STATE_SIZE, MellingerGains, mellinger_control


def _clip(val, lo, hi):
    return ca.fmin(ca.fmax(val, lo), hi)


class CompiledStepper:
    """Physics step for V vehicles given their RotorPy ``quad_params`` dicts.

    Arrays (filled by the caller before :meth:`step`, read after it):
    ``state`` (V, 17); ``ref`` (V, 12) position m, velocity m/s, acceleration m/s^2, world frame,
    and body-rate feed-forward rad/s, body frame (used by the Mellinger law only);
    ``ctrl_mem`` (V, CONTROLLER_STATE_SIZE) the Mellinger law's memory (zero at the start; the
    step writes the next one into ``next_ctrl_mem``);
    ``ext_force_N`` (V, 3) world frame; ``ext_torque_Nm`` (V, 3) world axes; ``ff_force_N`` (V, 3)
    world frame and ``ff_torque_Nm`` (V, 3) world axes: the predicted disturbance the controller
    compensates (zero: RotorPy's law; the torque is rotated into the body frame like the applied one).
    Outputs: ``next_state`` (V, 17); ``cmd_thrust_N`` (V, 4) commanded motor thrusts (unclipped);
    ``ctbm`` (V, 4) collective thrust N and body moments N m; ``saturated`` (V,) 1 where a motor
    command was clipped; ``accel_mps2`` (V, 3) true acceleration at the step start (gravity excluded).
    """

    def __init__(
        self,
        params: list[dict],
        dt_s: float,
        *,
        wind_mps=(0.0, 0.0, 0.0),
        controllers: list[MellingerGains | None] | None = None,
    ):
        self.n = len(params)
        ctrls = list(controllers) if controllers is not None else [None] * self.n
        self.dt_s = float(dt_s)
        n = self.n
        S = ca.SX.sym("S", n * STATE_SIZE)
        R = ca.SX.sym("R", n * 12)
        C = ca.SX.sym("C", n * CONTROLLER_STATE_SIZE)
        F = ca.SX.sym("F", n * 3)
        T = ca.SX.sym("T", n * 3)
        FF = ca.SX.sym("FF", n * 3)
        TF = ca.SX.sym("TF", n * 3)
        outs: dict[str, list] = {"next": [], "cmd": [], "ctbm": [], "sat": [], "acc": [], "mem": []}
        wind = [float(w) for w in wind_mps]
        for i, p in enumerate(params):
            vc = VehicleConstants.from_params(p)
            cc = ControllerConstants.from_params(p)
            s = [S[i * STATE_SIZE + k] for k in range(STATE_SIZE)]
            ref = [R[i * 12 + k] for k in range(12)]
            mem = [C[i * CONTROLLER_STATE_SIZE + k] for k in range(CONTROLLER_STATE_SIZE)]
            f_ext = [F[i * 3 + k] for k in range(3)]
            t_ext_w = [T[i * 3 + k] for k in range(3)]
            ff_f = [FF[i * 3 + k] for k in range(3)]
            ff_t_b = mat_t_vec(rotation(s[6:10]), [TF[i * 3 + k] for k in range(3)])
            gains = ctrls[i]
            if gains is None:
                speeds, thrusts, u1, u2 = se3_control(cc, s, ref[0:3], ref[3:6], ref[6:9], ff_f, ff_t_b)
                new_mem = list(mem)
                sat = 0
                for sp in speeds:
                    sat = sat + (sp > vc.speed_max_radps) + (sp < vc.speed_min_radps)
            else:
                capped, thrusts, u1, u2, new_mem = mellinger_control(gains, s, ref, mem, self.dt_s, ff_f, ff_t_b)
                speeds = [ca.sqrt(ca.fmax(f, 0.0) / vc.k_eta) for f in capped]
                sat = 0
                for f in thrusts:
                    sat = sat + (f > gains.max_motor_thrust_N + 1e-12) + (f < gains.min_motor_thrust_N - 1e-12)
            cmd = [_clip(sp, vc.speed_min_radps, vc.speed_max_radps) for sp in speeds]
            t_ext_b = mat_t_vec(rotation(s[6:10]), t_ext_w)

            def deriv(state, vc=vc, cmd=cmd, f_ext=f_ext, t_ext_b=t_ext_b):
                return state_derivative(vc, state, cmd, f_ext, t_ext_b, wind)

            h = self.dt_s
            k1 = deriv(s)
            k2 = deriv([s[j] + 0.5 * h * k1[j] for j in range(STATE_SIZE)])
            k3 = deriv([s[j] + 0.5 * h * k2[j] for j in range(STATE_SIZE)])
            k4 = deriv([s[j] + h * k3[j] for j in range(STATE_SIZE)])
            nxt = [s[j] + (h / 6.0) * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]) for j in range(STATE_SIZE)]
            qn = ca.sqrt(sum(nxt[6 + j] ** 2 for j in range(4)))
            for j in range(4):
                nxt[6 + j] = nxt[6 + j] / qn
                # RotorPy clips the rotor speeds of the new state to the motor range as well
                nxt[13 + j] = _clip(nxt[13 + j], vc.speed_min_radps, vc.speed_max_radps)
            outs["next"] += nxt
            outs["cmd"] += thrusts
            outs["ctbm"] += [u1] + list(u2)
            outs["sat"] += [ca.fmin(sat, 1)]
            outs["acc"] += k1[3:6]
            outs["mem"] += new_mem
        self.function = ca.Function(
            "proxplan_step",
            [S, R, F, T, FF, TF, C],
            [ca.vertcat(*outs[k]) for k in ("next", "cmd", "ctbm", "sat", "acc", "mem")],
            ["state", "ref", "ext_force", "ext_torque", "ff_force", "ff_torque", "ctrl_mem"],
            ["next", "cmd", "ctbm", "sat", "acc", "next_mem"],
        )
        self.state = np.zeros((n, STATE_SIZE))
        self.ref = np.zeros((n, 12))
        self.ctrl_mem = np.zeros((n, CONTROLLER_STATE_SIZE))
        self.next_ctrl_mem = np.zeros((n, CONTROLLER_STATE_SIZE))
        self.ext_force_N = np.zeros((n, 3))
        self.ext_torque_Nm = np.zeros((n, 3))
        self.ff_force_N = np.zeros((n, 3))
        self.ff_torque_Nm = np.zeros((n, 3))
        self.next_state = np.zeros((n, STATE_SIZE))
        self.cmd_thrust_N = np.zeros((n, 4))
        self.ctbm = np.zeros((n, 4))
        self.saturated = np.zeros(n)
        self.accel_mps2 = np.zeros((n, 3))
        self._buf, self._eval = self.function.buffer()  # CasADi's zero-copy evaluation buffers
        inputs = (
            self.state,
            self.ref,
            self.ext_force_N,
            self.ext_torque_Nm,
            self.ff_force_N,
            self.ff_torque_Nm,
            self.ctrl_mem,
        )
        for k, arg in enumerate(inputs):
            self._buf.set_arg(k, memoryview(arg))  # type: ignore[call-arg, arg-type]  # size from the buffer
        results = (self.next_state, self.cmd_thrust_N, self.ctbm, self.saturated, self.accel_mps2, self.next_ctrl_mem)
        for k, res in enumerate(results):
            self._buf.set_res(k, memoryview(res))  # type: ignore[call-arg, arg-type]

    def step(self) -> None:
        """Evaluate one step from the input arrays into the output arrays (in place)."""
        self._eval()

    def advance(self) -> None:
        """Copy ``next_state`` into ``state`` and the controller memory on (call after :meth:`step`)."""
        self.state[:] = self.next_state
        self.ctrl_mem[:] = self.next_ctrl_mem
