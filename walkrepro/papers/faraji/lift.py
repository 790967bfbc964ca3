"""Foot-lift, hip-switch and spring-compensation laws of Paper II (Eqs. 21-24, 28-30).

All are small closed-form functions of the phase time t ∈ [0, T) since the last touchdown.
"""

from __future__ import annotations

import math


def pelvis_roll(t: float, step_time: float, amplitude: float) -> float:
    """Pelvis roll δθ_roll = A sin(π t / T) (Eq. 22, A = 0.1 rad), lifting the swing hip [rad]."""
    return amplitude * math.sin(math.pi * t / step_time)


def fixed_lift(t: float, step_time: float, amplitude: float) -> float:
    """Swing-foot half-sine lift δz_fixed = A sin(π t / T) (Eq. 23, A = 0.01 m) [m]."""
    return amplitude * math.sin(math.pi * t / step_time)


def hip_angle_estimate(pelvis_swing_error: float, pelvis_height: float) -> float:
    """θ̂_act ≈ arctan((e₂ − e₁)/z) of Eq. (28), from the filtered errors [rad].

    Paper II's relative vectors (Eq. 7, Fig. 1) are s₁ = f − s and s₂ = p − s, so its
    e₂ − e₁ is the error of p − f, the pelvis-to-swing-foot vector. walkrepro's core orders
    e = [p − f, p − s, ḟ, ṗ] (note ``3lp.md`` §4), so the argument here is the error of its
    first component, Δ(p − f) [m]; positive when the swing foot is left behind.
    """
    return math.atan(pelvis_swing_error / pelvis_height)


def adaptive_lift(t: float, step_time: float, theta_hat: float, pelvis_height: float) -> float:
    """Extra swing lift δz_adaptive = z (1 − cos θ̂) sin(π t / T) (Eq. 29) [m]."""
    return pelvis_height * (1.0 - math.cos(theta_hat)) * math.sin(math.pi * t / step_time)


def foot_pitch_feedback(theta_hat: float) -> float:
    """Foot-orientation feedback δθ_pitch = −θ̂_act (Eq. 30) [rad].

    In coman's convention (+pitch about y = toes down) a swing foot left behind the pelvis
    (θ̂ > 0) is turned toes up, which undoes the leg's backward rotation.
    """
    return -theta_hat


def hip_switch_gamma(t: float, t1: float, swing: bool) -> float:
    """Weight γ of the hip transition law (Eq. 24).

    γ = 1 − exp(−(t/t₁)²) in swing (joint tracking takes over) and exp(−(t/t₁)²) in stance
    (torso regulation takes over), with t₁ = 0.2 T.
    """
    g = math.exp(-((t / t1) ** 2))
    return 1.0 - g if swing else g


def knee_compensation(contact_force: float, weight: float, mean_deflection: float) -> float:
    """Magnitude of the knee spring compensation |F| / (m g) · μ of Eq. (21) [rad].

    Paper II writes it with a minus sign in its joint convention; the signed offset for
    coman's convention is :func:`knee_target_offset`.
    """
    return abs(contact_force) / weight * mean_deflection


def knee_target_offset(contact_force: float, weight: float, mean_deflection: float) -> float:
    """Offset added to a knee motor target for its spring deflection (Eq. 21) [rad].

    A loaded knee spring lets the link bend by μ·|F|/(m g) more than the motor, so the
    motor is commanded that much less bent (in coman's convention, knee > 0 is flexion).
    """
    return -knee_compensation(contact_force, weight, mean_deflection)
