"""Quiet PyBullet connections."""

from __future__ import annotations

import os

from artic.sim.bullet import connect_direct, quiet_c_output


def test_quiet_c_output_silences_then_restores_the_descriptors(capfd):
    with quiet_c_output():
        os.write(1, b"hidden out\n")
        os.write(2, b"hidden err\n")
    os.write(1, b"shown out\n")
    os.write(2, b"shown err\n")
    out, err = capfd.readouterr()
    assert out == "shown out\n" and err == "shown err\n"


def test_connect_direct_prints_nothing_and_simulates(capfd):
    client = connect_direct()
    try:
        assert client.getNumBodies() == 0
        body = client.createMultiBody(baseMass=1.0)
        assert client.getNumBodies() == 1 and body == 0
    finally:
        client.disconnect()
    out, _ = capfd.readouterr()
    assert "argv" not in out
