"""The kernels the step loop and the contact loops call many times per step are compiled
without numba's reference counting (``engine.kernels.jit.item_kernel``): with it, every call paid an
atomic increment and decrement per array argument, which was half of a wedge step
(benchmarks/wedge_study.py; perf showed NRT_incref/NRT_decref at 47 % of the step loop).
This checks the flag on each of them, so that a kernel rewritten with a plain ``njit`` is
caught here rather than as a slower benchmark."""
from __future__ import annotations

import inspect

import pytest

from engine.kernels import bodies, body_contacts, contacts, mesh_contact, neighbours, stepper

PER_ITEM = {
    contacts: ("_pair_contacts", "point_segment_max_overlap", "best_of_neighbours",
               "crossing_weight_forces"),
    body_contacts: ("_bristle_body_candidate", "closest_triangle", "closest_features",
                    "supported_face", "_cell_face_in_front",
                    "nearest_triangle",
                    "deep_closest", "feature_normal", "_point_fade_forces",
                    "_mesh_fade_forces", "_edge_fade_forces", "_holds_edge",
                    "edge_face_fade", "_beyond_an_edge"),
    neighbours: ("predicted_displacement", "node_displacement", "body_displacement",
                 "lists_stale"),
    stepper: ("check_state", "local_damping", "add_gravity",
              "add_loads", "roots_follow", "roots_to_bodies"),
    bodies: ("bodies_half_kick", "bodies_drift", "kinematic_state"),
    mesh_contact: ("_find_points_in_body", "_apply_hits"),
}


@pytest.mark.parametrize("module,name", [(m, n) for m, names in PER_ITEM.items()
                                         for n in names])
def test_hot_kernel_compiled_without_reference_counting(module, name):
    fn = getattr(module, name)
    assert fn.targetoptions.get("_nrt") is False, (
        f"{module.__name__}.{name} is compiled with reference counting: decorate it with "
        f"engine.kernels.jit.item_kernel (it must not allocate)")


def test_every_njit_kernel_of_the_contact_modules_is_listed_or_allocates():
    """A new per-item kernel in the contact modules is either listed above (and so checked)
    or compiled with reference counting because it allocates or runs once per step."""
    allowed_with_nrt = {
        contacts: {"segment_bounds", "build_pair_list", "bristle_bristle_narrow",
                   "scatter_bristle_bristle"},
        # once per rebuild: copies slices of the lists
        neighbours: {"rebuild_lists", "carry_history", "build_body_list"},
        body_contacts: {"build_body_candidates", "bristle_body_narrow",
                        "scatter_bristle_body", "body_body_contacts"},
        # once per step (allocates each pair's hit buffers), and the build-time check
        mesh_contact: {"mesh_mesh_contacts", "_deepest_points"},
    }
    for module, allowed in allowed_with_nrt.items():
        for name, fn in inspect.getmembers(module):
            opts = getattr(fn, "targetoptions", None)
            if opts is None or getattr(fn, "__module__", None) != module.__name__:
                continue
            if opts.get("inline") == "always":
                continue  # compiled into its caller, with the caller's flags
            if opts.get("_nrt") is False:
                assert name in PER_ITEM[module], f"{name}: add it to PER_ITEM"
            else:
                assert name in allowed, (
                    f"{module.__name__}.{name} has reference counting: use item_kernel, or "
                    f"list it here with the reason it needs it")
