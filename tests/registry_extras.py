"""A fill method and an export format registered for a while, for the tests of what the registries feed."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from handmocap.core.gaps import FillMethod, register_fill_method, unregister_fill_method
from handmocap.core.review.export_formats import ExportFormat, register_export_format, unregister_export_format


@contextmanager
def registered_extras() -> Iterator[None]:
    """A fill method "hold" (the sample before the gap held) and an export format "names", registered for the
    block and unregistered after it."""
    register_fill_method(FillMethod(name="hold", label="Hold", description="The sample before the gap held",
                                    needs="", code=42, colour=(10, 20, 30), reach=1, menu_rank=9,
                                    fill=lambda positions, marker, start, length, _c, _a: np.repeat(
                                        positions[start - 1:start, marker], length, axis=0)))
    register_export_format(ExportFormat(name="names", label="Label names", suffixes=(".txt",), name_tag="_names",
                                        batch_ending=".names.txt", writer=lambda review, path, options: [path]))
    try:
        yield
    finally:
        unregister_fill_method("hold")
        unregister_export_format("names")
