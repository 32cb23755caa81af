"""Predict the deployed shape of a printed layout (issue 12): a homogenized thin-shell simulation.

- ``rest_forms``: ribbons as placed -> per-face coverage, rest first and second fundamental forms;
- ``shell``: the discrete shell energy (Chen et al. 2018) with analytic gradient and Hessian;
- ``solver``: Newton's method with six pinned degrees of freedom;
- ``compare``: Kabsch registration and the deviation from the target (Table 1's "Dev.");
- ``picture``: ``deployed.png``;
- ``predict``: ``predict_deployed``, the top level.

Pure functions on arrays; no I/O.
"""

from .picture import render_deployed_png
from .predict import Material, Prediction, predict_deployed

__all__ = ["Material", "Prediction", "predict_deployed", "render_deployed_png"]
