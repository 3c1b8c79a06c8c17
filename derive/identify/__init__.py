"""Identification: from a logged run of the arm to identified parameters (issue 22).

Beside :mod:`derive.control` (imports flow model -> dynamics -> identify -> codegen -> cli):

* :mod:`derive.identify.parameters`: the standard parameters (ten per body, rotor inertia,
  viscous and Coulomb friction per joint);
* :mod:`derive.identify.regressor`: Y of J theta'' + G = Y pi in the base parameters pi,
  from the recursion J and the bias come from (derive generate --regressor emits it);
* :mod:`derive.identify.excite`: the Fourier excitation trajectory (derive excite);
* :mod:`derive.identify.log`, :mod:`derive.identify.exclude`, :mod:`derive.identify.signals`:
  reading logged runs, the samples they keep (a valid column, --exclude rules, joins),
  filtering and differentiating each stretch on its own;
* :mod:`derive.identify.estimate`, :mod:`derive.identify.prior`, :mod:`derive.identify.consistent`,
  :mod:`derive.identify.run`: weighted least squares, the arm file as a prior and the physically
  consistent (LMI, maximum a posteriori) estimate (derive identify);
* :mod:`derive.identify.quality`: the findings (warnings, refusals) on the result;
* :mod:`derive.identify.armfile`, :mod:`derive.identify.report`: the identified arm file and
  the report;
* :mod:`derive.identify.payload`, :mod:`derive.identify.payload_file`: only the payload on the last
  body, with the rest known (derive identify --payload): its ten parameters, their uncertainty, the
  ``[payload]`` table.
"""

CUTOFF = 10.0     # Hz: derive identify's default low-pass cut-off (derive.identify.signals)
HARMONICS = 5     # derive excite's default harmonics per joint (derive.identify.excite)
