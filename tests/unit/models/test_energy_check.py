"""check_energy's tolerance (models/energy.py): rtol × scale plus the work the closed patches'
unresolved normal jumps can do (Newton's tolerance on the contact rows), no more."""

from dataclasses import replace

from polypore.models.energy import EnergyTerms, check_energy


def _terms(balance_deficit, unresolved):
    # a step whose only terms are a source work and a viscous dissipation exceeding it by the deficit
    return EnergyTerms(time=1.0, dt=1.0, elastic=0.0, storage=0.0, delta_elastic=0.0, delta_storage=0.0,
                       friction_dissipation=0.0, viscous_dissipation=1.0 + balance_deficit, viscous_matrix=0.0,
                       viscous_fracture=0.0, viscous_exchange=0.0, contact_normal=-balance_deficit,
                       contact_tangential_excess=0.0, numerical_dissipation=0.0, load_work=0.0, reaction_work=0.0,
                       fluid_source_work=1.0, fluid_boundary_work=0.0, scale=2.0, unresolved_normal=unresolved)


def test_unresolved_normal_work_is_tolerated_up_to_its_bound():
    assert check_energy([_terms(1e-8, 0.0)]) != []               # 1e-8 > 1e-9 × 2
    assert check_energy([_terms(1e-8, 2e-8)]) == []              # within the unresolved jumps' work
    assert check_energy([_terms(1e-7, 2e-8)]) != []              # beyond it
    assert check_energy([replace(_terms(1e-9, 0.0), scale=2.0)]) == []
