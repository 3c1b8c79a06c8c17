"""The plant FMU as the tests drive it (FMI 3, fmpy): built by derive.fmu.plant_fmu, validated and
unzipped; run under a held input with tunable values set in initialization mode; and derive's Python plant
(derive.sim.plant.Plant) run on the same input, the reference it must match."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest


def built(d, folder: Path):
    """(model description, {name: variable}, {name: value reference}, unzipped folder) of ``d``'s plant FMU,
    which fmpy validates without a problem."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    from derive.fmu import plant_fmu

    name, data = plant_fmu(d, 3)
    path = folder / name
    path.write_bytes(data)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    variables = {v.name: v for v in md.modelVariables}
    with zipfile.ZipFile(path) as z:
        z.extractall(folder / "unzipped")
    return md, variables, {k: v.valueReference for k, v in variables.items()}, folder / "unzipped"


def fmu_run(fmu_files, s, steps: int, u: np.ndarray, start: dict[str, float],
            refused: dict[str, float] | None = None) -> np.ndarray:
    """theta (steps x 2) of the FMU of ``built`` over ``steps`` samples of ``s.sample_time`` under the held
    input ``u``, the tunables ``start`` set in initialization mode; then each of ``refused`` must be
    refused by the setter (fmi3Error, status 3)."""
    from fmpy.fmi3 import FMU3Slave

    md, _, vr, folder = fmu_files
    fmu = FMU3Slave(guid=md.guid, unzipDirectory=str(folder), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="plant")
    fmu.instantiate()
    fmu.enterInitializationMode(startTime=0.0)
    if start:
        fmu.setFloat64([vr[k] for k in start], list(start.values()))
    fmu.exitInitializationMode()
    out = []
    for k in range(steps):
        fmu.setFloat64([vr["u[1]"], vr["u[2]"]], list(u))
        fmu.doStep(k * s.sample_time, s.sample_time)
        out.append(fmu.getFloat64([vr["theta[1]"], vr["theta[2]"]]))
    for key, value in (refused or {}).items():
        with pytest.raises(Exception, match="status 3"):
            fmu.setFloat64([vr[key]], [value])
    fmu.terminate()
    fmu.freeInstance()
    return np.array(out)


def plant_run(d, s, steps: int, u: np.ndarray) -> np.ndarray:
    """theta (steps x n) of derive's Python plant with settings ``s`` under the held input ``u``."""
    from derive.sim.plant import Plant, true_plant

    plant = Plant(d, true_plant(d, s))
    plant.reset(s.initial_theta, 1)
    out = []
    for _ in range(steps):
        plant.step(u[None, :], s.sample_time, s.substeps)
        out.append(plant.theta[0].copy())
    return np.array(out)
