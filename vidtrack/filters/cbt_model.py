"""A learned Channel-Based Tracking motion model and its ``.npz`` file.

The model of :class:`~vidtrack.filters.cbt.CBTFilter`: per axis, a
displacement conditional ``D[d_k, d_{k-1}, ..., d_{k-n+1}]`` on a cos²
channel basis (:mod:`vidtrack.channels`), displacements measured in box sizes
``sqrt(w h)`` so that a model learned on one sequence applies to another.
``vidtrack learn cbt`` estimates it by the normalised covariance (eq. 11 of
Felsberg & Larsson, "Learning Object Tracking in Image Sequences") and writes
it with :meth:`CBTModel.save`; ``--model FILE`` (the ``model`` option of
``cbt``) reads it with :meth:`CBTModel.load`.

File layout (NumPy ``.npz``, no pickles): ``kind = "cbt"``, the basis
``lo``, ``hi``, ``n`` and the arrays ``Dx``, ``Dy`` of shape ``(n,) * order``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..channels import ChannelBasis
from ..errors import UsageError


@dataclass(frozen=True)
class CBTModel:
    """A learned CBT motion model: per-axis displacement conditionals in box units.

    ``Dx``, ``Dy`` are ``(C,) * order`` tensors ``D[d_k, d_{k-1}, ...]`` on
    ``basis`` (displacements divided by the box size ``sqrt(w h)``), so a
    model learned on one sequence applies to another.
    """

    basis: ChannelBasis
    Dx: np.ndarray
    Dy: np.ndarray

    @property
    def order(self) -> int:
        return self.Dx.ndim

    def save(self, path) -> None:
        """Write the model to ``path`` (a file name or an open binary file) as ``.npz``."""
        np.savez(path, kind="cbt", lo=self.basis.lo, hi=self.basis.hi, n=self.basis.n, Dx=self.Dx, Dy=self.Dy)

    @classmethod
    def load(cls, path) -> "CBTModel":
        """Read a model written by :meth:`save`.

        Raises
        ------
        UsageError
            For a missing file, a file that is not such a model, or arrays
            that do not fit together (one line naming the file).
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                if str(data["kind"]) != "cbt":
                    raise UsageError(f"--model {path}: not a CBT model (kind {data['kind']!s})")
                basis = ChannelBasis(float(data["lo"]), float(data["hi"]), int(data["n"]))
                Dx, Dy = np.asarray(data["Dx"], float), np.asarray(data["Dy"], float)
        except UsageError:
            raise
        except FileNotFoundError:
            raise UsageError(f"--model {path}: no such file") from None
        except Exception as exc:  # zip errors, missing keys, bad values
            raise UsageError(f"--model {path}: not a CBT model file (expected a .npz written by "
                             f"'vidtrack learn cbt'; {type(exc).__name__})") from None
        if Dx.shape != Dy.shape or Dx.ndim < 1 or any(s != basis.n for s in Dx.shape) \
                or not (np.all(np.isfinite(Dx)) and np.all(np.isfinite(Dy))):
            raise UsageError(f"--model {path}: inconsistent CBT model arrays")
        return cls(basis, Dx, Dy)
