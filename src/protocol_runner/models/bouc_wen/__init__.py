"""Generalised Bouc-Wen hysteresis model of a joint's torque-angle loop (thesis §6.2, Eq 19-25).

The thesis extends the Bouc-Wen model (Eq 20, ``dz = dx [A - |z|^n Psi]``) with a shape function that also
depends on the sign of the angle, so that asymmetric loops can be represented (§6.2.3, Eq 22)::

    Psi = b1 sgn(dx z) + b2 sgn(dx x) + b3 sgn(x z) + b4 sgn(dx) + b5 sgn(z) + b6 sgn(x)

and discretises it with the explicit first-order recursion of Eq 23::

    z_0 = initial torque
    z_{i+1} = z_i + (x_{i+1} - x_i) [A - |z_i|^n Psi_i]

whose torque depends on the sampling rate. :func:`simulate` and :func:`fit` integrate the differential
equation instead (``scheme="refined"``, :mod:`.schemes`); the literal recursion is ``scheme="eq23"``.

``x`` is the joint angle in degrees and ``z`` the torque in N*m (``A`` in N*m/deg, each ``beta_k`` in
N*m^(1-n)/deg). Eq 22 is garbled in the available copy; the sign terms above are those of Eq 23, which
Table 4 confirms. The six sign patterns met on a centred loop are the six phases of Table 4; their shape
values ``psi = M24 @ beta`` (Eq 24) are inverted by Eq 25, ``beta = M25 @ psi``. The other two patterns,
(x > 0, dx > 0, z < 0) and (x < 0, dx < 0, z > 0), are not phases of Table 4 but Eq 23 still applies; with
the Figure 57 parameters the second is unstable, which is why divergence is detected.

``sgn(0) = 0`` as in Eq 23 (a sample where the angle does not move leaves the torque unchanged). The model
depends only on the angle path, not on time. :func:`fit` does not centre the trials (note under Table 4):
the caller does. Fitting (§6.2.3, Figure 56) is in :mod:`.fitting`: least squares with the analytic
Jacobian from several starts, keeping the best (§6.2.5: the fit "depends a lot on the initial conditions").
"""
