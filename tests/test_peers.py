"""The peer engines' adapters (sandbox/peers.py) on scenes whose answer we know; skipped where
the ``peers`` extra is not installed (CI installs only ``test``)."""

import numpy as np
import pytest

from sandbox import Scene
from sandbox.errors import SandboxError
from sandbox.peers import PEERS
from sandbox.scene.library import resolve_scene


@pytest.mark.parametrize("name", ["pybullet", "rapier-t1", "rapier-t2"])
def test_a_resting_box_stays_put_and_its_contacts_are_measured(name):
    peer = PEERS[name]
    ok, why = peer.available()
    if not ok:
        pytest.skip(why)
    world = peer.open(Scene.load(resolve_scene("box_on_plane")), 10)
    start = world.position(0)
    for _ in range(60):
        world.step()
    m = world.metrics()
    moved = np.linalg.norm(world.position(0) - start)
    world.close()
    assert moved < 0.01
    assert m["contacts"] >= 2  # a resting face (pybullet keeps two of its corners here, Rapier four)
    assert 0.0 <= m["max_penetration"] < 0.01  # soft contacts sink a little, from the poses, not stale depths
    assert m["kinetic_energy"] < 1e-3


def test_rapier_refuses_a_scene_it_cannot_translate():
    peer = PEERS["rapier-t1"]
    if not peer.available()[0]:
        pytest.skip(peer.available()[1])
    with pytest.raises(SandboxError, match="only box-and-plane scenes"):
        peer.open(Scene.load(resolve_scene("mixed_on_terrain")), 10)
