"""Paper III (Jo & Oh): ZMP preview walking, impedance landing and the centroidal-momentum QP.

Modules: :mod:`.footsteps` (footstep plan, ZMP reference, swing trajectory),
:mod:`.preview` (LIPM CoM–ZMP preview control, the paper's ref. [23]), :mod:`.impedance`
(Eqs. 1–3), :mod:`.centroidal_qp` (Eqs. 5–9 and the QP of §III-D) and
:mod:`.controller` (the controller registered as ``qpimpedance``).
"""
