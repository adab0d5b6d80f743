"""Bake settings: preset < sidecar [bake] < command line, and clear errors for bad values."""
import pytest

from glint.bake.settings import PRESETS, resolve_settings
from glint.core.errors import GlintError


def test_precedence():
    s = resolve_settings({"quality": "draft", "samples": 7})
    assert s.quality == "draft" and s.samples == 7
    assert s.texels_per_metre == PRESETS["draft"]["texels_per_metre"]
    s = resolve_settings({"quality": "draft", "samples": 7}, quality="final", samples=9, jobs=None)
    assert s.quality == "final" and s.samples == 9 and s.jobs == 0
    assert resolve_settings({"jobs": 1}, jobs=None).workers == 1


def test_transport_settings_exclude_jobs():
    a, b = resolve_settings({}, jobs=1), resolve_settings({}, jobs=2)
    assert a.transport_dict() == b.transport_dict()
    assert resolve_settings({}, samples=3).transport_dict() != a.transport_dict()


@pytest.mark.parametrize("sidecar, words", [
    ({"samples": "x"}, ["samples", "whole number"]),
    ({"samples": 2.5}, ["samples"]),
    ({"samples": 0}, ["samples"]),
    ({"denoise": 1}, ["denoise", "true or false"]),
    ({"texels_per_metre": float("nan")}, ["texels_per_metre"]),
    ({"quality": "ultra"}, ["ultra", "draft"]),
])
def test_bad_values(sidecar, words):
    with pytest.raises(GlintError) as e:
        resolve_settings(sidecar)
    for w in words:
        assert w in str(e.value)
