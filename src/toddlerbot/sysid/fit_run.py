"""What `sysid fit` and `sysid eval` do around the fit itself: parameter files checked against the manifest's
motor, and the provenance a fitted ``params.json`` records."""

from __future__ import annotations

from pathlib import Path

from toddlerbot.actuation.motor_params import MotorParams
from toddlerbot.actuation.params_file import load_params
from toddlerbot.sysid.errors import SysIDError
from toddlerbot.sysid.fit import FitResult
from toddlerbot.sysid.manifest import Manifest


def params_for(path: Path, manifest: Manifest, manifest_path: Path) -> MotorParams:
    """The parameters in `path`, refused in one line where they are for another motor model than the manifest's."""
    name, params = load_params(path)
    if name != manifest.motor.name:
        raise SysIDError(f"{path}: parameters are for {name}, but {manifest_path} is a {manifest.motor.name}")
    return params


def fit_provenance(manifest: Manifest, manifest_path: Path, model: str, seed: int, result: FitResult) -> dict:
    """How the parameters were fitted: the runs, the search, its outcome and each parameter's uncertainty."""
    return {
        "manifest": str(manifest_path), "runs": len(manifest.runs), "kp": sorted({r.kp for r in manifest.runs}),
        "rig": manifest.rig.type, "seed": seed, "evals": result.evals, "generations": result.generations,
        "restarts": result.restarts, "rmse_deg": result.rmse_deg, "wall_s": round(result.wall_s, 2), "model": model,
        "at_bounds": result.at_bounds,
        "uncertainty": {name: {"std": u.std, "relative": u.relative,
                               "strongest_correlation": list(u.strongest_correlation)}
                        for name, u in result.uncertainty.items()},
        "fixed": result.fixed,
    }
