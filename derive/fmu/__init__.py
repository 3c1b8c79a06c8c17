"""FMI packaging of the generated controller (``derive fmu``).

:func:`controller_fmu` builds a co-simulation FMU (FMI 2.0 or 3.0) of one
controller form from a Derivation, :func:`plant_fmu` one of the arm's
simulation plant (derive.fmu.plant); :func:`write_fmus` writes FMUs atomically.
The variables and their descriptions are views (:mod:`derive.fmu.describe`),
the C glue is a template (``templates/fmu/``) that only calls the generated
API, and the FMI headers are the standard's own (``headers/``, BSD-2-Clause).
"""
from derive.fmu.package import FMI_VERSIONS, FmuOptions, check_options, controller_fmu, plant_fmu, write_fmus

__all__ = ["FMI_VERSIONS", "FmuOptions", "check_options", "controller_fmu", "plant_fmu", "write_fmus"]
