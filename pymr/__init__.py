"""pymr: flexible multibody dynamics with multirate Nordsieck Adams integration.

The numerical kernel is Fortran (``pymr._core``, built by meson-python with f2py);
this package runs scenes, loads results and drives studies and benchmarks.
"""
from __future__ import annotations

from .results import Results, load_results
from .api import (PymrError, SceneError, ArgumentTypeError, SolverError, OutputError, ResultsError, ResultsKeyError, run, model_terms, model_accelerations, step_history, marker_shapes,
                  model_energy, model_size, write_modal_file, loop_rows, Model,
                  force_response, modes, Modes)

from .scene import Scene, schema
from .modal_import import modal_import, ModalBody
from .errors import PymrWarning
from .plot import PlotError
from .sweep import SweepError

__version__ = "0.1.0"

__all__ = ["PymrError", "SceneError", "ArgumentTypeError", "SolverError", "OutputError", "ResultsError", "ResultsKeyError", "Results", "load_results", "run",
           "model_terms", "model_accelerations", "step_history", "marker_shapes", "model_energy", "model_size", "write_modal_file", "loop_rows",
           "modal_import", "ModalBody", "PymrWarning",
           "Model", "force_response", "modes", "Modes", "PlotError", "SweepError", "Scene", "schema",
           "__version__"]
