"""Structure models from NASTRAN: BDF + OP4/DMIG matrices, or OP2 modes.

Pipeline (:func:`import_nastran`), one module per stage::

    BDF (grids, frames, members, SPCs, RBE2/RBAR/MPC, ASET/QSET)  deck.py
    OP4 K, M (KGG/MGG, KAA/MAA; ASCII read in double), DMIG, or OP2
    matrix data blocks (OUTPUT2 of KAA/MAA, KGG/MGG)              matrices.py
        -> declared units to SI -> piezo stacks replace members (Eq. 1)
        -> rigid elements and MPCs: u_g = T u_n                    rigid.py
        -> constrained (SPC, a fixed boundary) and empty DOFs removed, massless
           DOFs of an a-set condensed
        -> structfmu.reduce.reduce_matrices: eigenvectors + Gram-Schmidt Ritz (Eq. 3-8)
    or SOL 103 OP2 eigenvalues + eigenvectors (+ RESVEC residual vectors)  modes.py
    -> ReducedModel (the same object the built-in trusses give) -> structure FMU
                                                                   importer.py

pyNastran is imported through :mod:`structfmu.nastran.pyn` (numpy 2, its log kept
quiet); what the import is asked for is in :mod:`structfmu.nastran.spec`; test data and
exported decks are written by :mod:`structfmu.nastran.writers`.

Conventions
-----------
* Units: the BDF and the matrices are in one declared system (:data:`UNIT_SYSTEMS`:
  ``"SI"``, ``"in-lbf-s"``, ``"mm-t-s"``), converted to SI here; the rest of the suite
  is SI.  A model without a declared system is an error.
* DOFs: a matrix row is ``(grid, component)``, component 1-3 translations and 4-6
  rotations in the grid's displacement coordinate system (GRID field CD), 0 for a
  scalar point.  By default the matrices are the g-set (every grid x 6 and every
  SPOINT, sorted by id, as NASTRAN orders them); an a-set (KAA/MAA) needs its DOF map.
* Constraints: DOFs of SPC/SPC1 cards (all sets) and GRID PS fields are removed, and so
  are DOFs whose stiffness and mass rows are both empty (the rotations of a rod-only
  grid: what NASTRAN's AUTOSPC removes).
* Actuators: an axial member (CROD, CONROD, CBAR, CBEAM) becomes the piezo stack of Eq.
  (1): its axial stiffness ``E A / L`` is replaced by the stack's ``k_e`` and its mass by
  the stack's mass (lumped, or coupled when the BDF has PARAM,COUPMASS,1), on the
  translations of its end grids (bending and torsion of bars and beams are kept).  The
  input ``fc_<name>`` (N) pushes the end grids apart along the member; the outputs
  ``elong_<name>`` (m) and ``strain_<name>`` (1, on the gauge element if one is given,
  else on the stack) read it.
"""

from __future__ import annotations

from structfmu.nastran.deck import Constraint, Deck, gset, read_deck, read_dof_map
from structfmu.nastran.importer import import_nastran
from structfmu.nastran.matrices import op4_precision, read_dmig, read_matrices, read_op4
from structfmu.nastran.modes import read_modes
from structfmu.nastran.pyn import pynastran
from structfmu.nastran.spec import (UNIT_SYSTEMS, Actuator, Channel, LineOfSight,
                                    NastranError, NastranWarning, Point, Stack, UnitSystem,
                                    parse_actuator, parse_los, parse_point, unit_system)
from structfmu.nastran.writers import write_matrices_op2, write_modes_op2, write_truss_deck

__all__ = ["UNIT_SYSTEMS", "UnitSystem", "Stack", "Actuator", "Point", "LineOfSight",
           "Channel", "NastranError", "NastranWarning", "import_nastran",
           "parse_actuator", "parse_point", "parse_los", "write_truss_deck", "read_deck",
           "write_modes_op2", "write_matrices_op2", "read_modes", "read_matrices", "read_op4", "read_dmig",
           "read_dof_map", "op4_precision", "unit_system", "Deck", "Constraint"]

# names the tests and benchmarks used before the split into modules
_pynastran = pynastran
_gset = gset
