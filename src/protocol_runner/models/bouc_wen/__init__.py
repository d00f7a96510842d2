"""Generalised Bouc-Wen hysteresis model of a joint's torque-angle loop (thesis §6.2, Eq 19-25).

The thesis extends the Bouc-Wen model (Eq 20, ``dz = dx [A - |z|^n Psi]``) with a shape function that also
depends on the sign of the angle, so that asymmetric loops (a joint that behaves differently when stretched
and compressed) can be represented (§6.2.3, Eq 22)::

    Psi = b1 sgn(dx z) + b2 sgn(dx x) + b3 sgn(x z) + b4 sgn(dx) + b5 sgn(z) + b6 sgn(x)

The thesis discretises it with the explicit first-order recursion of Eq 23::

    z_0 = initial torque
    z_{i+1} = z_i + (x_{i+1} - x_i) [A - |z_i|^n Psi_i]

whose torque depends on the sampling rate.  :func:`simulate` and :func:`fit` integrate the differential
equation instead (``scheme="refined"``, the default): the angle is taken as piecewise linear between samples
and the state is advanced by Heun's method on substeps bounded by an angle increment and by the loop's
stiffness (:mod:`.schemes`), so a parameter set gives the same torque at any sampling rate.  The literal
recursion is ``scheme="eq23"``.

where ``x`` is the joint angle in degrees and ``z`` is the torque in N*m (so ``A`` is in N*m/deg and each
``beta_k`` in N*m^(1-n)/deg).  (Eq 22 is garbled in the available copy of the thesis; the sign terms above
are those of Eq 23, which Table 4 confirms.)  The six sign patterns met on a centred loop are the six
phases of Table 4; their shape values ``psi = M24 @ beta`` (Eq 24) are inverted by Eq 25,
``beta = M25 @ psi``.  The other two sign patterns, (x > 0, dx > 0, z < 0) and (x < 0, dx < 0, z > 0), are
not phases of Table 4 but Eq 23 still applies there; with the Figure 57 parameters the second one is
unstable (a recursion started there with a few N*m diverges), which is why divergence is detected.

Units and conventions:

* ``sgn(0) = 0``, exactly as the signum function in Eq 23; a sample where the angle does not move leaves the
  torque unchanged.
* The model depends only on the angle path, not on time (it is rate-independent); decimating smooth data
  for the fit keeps every sample's angle path and drops residuals only (see :func:`fit`).
* The thesis centres each trial on (0, 0) before fitting (note under Table 4).  :func:`fit` does *not*
  centre: the caller (the analysis pipeline) does.

Fitting (§6.2.3, Figure 56) is in :mod:`.fitting`: least squares with the analytic Jacobian from several
starts, keeping the best optimum (§6.2.5: the thesis fit "depends a lot on the initial conditions").
"""
