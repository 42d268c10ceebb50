"""Hypothesis strategies for frames, built from the spec tables (shared by every test module)."""

from __future__ import annotations

from hypothesis import strategies as st

from xac1_proto import FRAME_CLASSES, Frame, spec


def field_values(fs: spec.FrameSpec, name: str) -> st.SearchStrategy[int | str]:
    field = spec.FIELDS[name]
    if field.text:
        return st.text("0123456789", min_size=field.width, max_size=field.width)
    lo, hi = fs.field_range(name)
    return st.integers(lo, hi)


def frames_of(key: tuple[str, str]) -> st.SearchStrategy[Frame]:
    fs = spec.SPECS[key]  # type: ignore[index]
    cls = FRAME_CLASSES[fs.key]
    return st.fixed_dictionaries({n: field_values(fs, n) for n in fs.field_names}).map(
        lambda kw: cls(**kw))


def frames(role: str | None = None) -> st.SearchStrategy[Frame]:
    keys = [k for k in spec.SPECS if role is None or k[1] == role]
    return st.sampled_from(keys).flatmap(frames_of)
