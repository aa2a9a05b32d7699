import numpy as np
import pytest

from structfmu.fem import Truss


def rod_chain(n_el=10, length=1.0, EA=1e6, rho_a=2.0, mass_type="consistent", fixed=True):
    """A straight chain of rods along x, fixed at node 0 (all DOFs of the others but
    the axial one fixed too, so only axial motion remains)."""
    x = np.linspace(0, length, n_el + 1)
    nodes = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    el = np.c_[np.arange(n_el), np.arange(1, n_el + 1)]
    le = length / n_el
    fixed_dofs = [3 * i + d for i in range(n_el + 1) for d in (1, 2)]
    if fixed:
        fixed_dofs += [0]
    return Truss(nodes, el, np.full(n_el, EA / le), np.full(n_el, rho_a * le),
                 np.zeros(n_el + 1), fixed_dofs=np.array(fixed_dofs), mass_type=mass_type,
                 name="rod")


@pytest.fixture(scope="session")
def truss10_full():
    from structfmu.models import truss10
    return truss10.build()


@pytest.fixture(scope="session")
def truss10_reduced(truss10_full):
    from structfmu.models import truss10
    from structfmu.reduce import reduce
    model, T = reduce(truss10_full, 6, damping=truss10.damping(6), return_basis=True)
    return model, T
