"""Shared helpers for scene tests: tiny hand-built meshes written into tmp_path."""

from __future__ import annotations

import numpy as np
import pytest


def write_glb(path, meshes):
    """Write a GLB from [(node_name, vertices_yup (n,3), faces (m,3), transform 4x4|None)]."""
    import trimesh

    sc = trimesh.Scene()
    for name, v, f, T in meshes:
        m = trimesh.Trimesh(vertices=np.asarray(v, float), faces=np.asarray(f), process=False)
        sc.add_geometry(m, node_name=name, geom_name=name, transform=T)
    path.write_bytes(sc.export(file_type="glb"))
    return path


def quad_yup(x0, x1, depth0, depth1, height=0.0):
    """A horizontal quad in glTF y-up coordinates: x in [x0, x1], world y in [depth0, depth1].

    World y = -z_gltf, so z_gltf runs over [-depth1, -depth0]. Faces wind CCW seen from +y.
    """
    v = np.array(
        [[x0, height, -depth0], [x1, height, -depth0], [x1, height, -depth1], [x0, height, -depth1]],
        float,
    )
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return v, f


@pytest.fixture
def cli_main(monkeypatch):
    """aerial_synth.cli.main restricted to the scene commands (other packages may not exist yet)."""
    import aerial_synth.cli as cli

    monkeypatch.setattr(cli, "COMMANDS", {k: v for k, v in cli.COMMANDS.items() if v[0] == "aerial_synth.scene.cli"})
    return cli.main
