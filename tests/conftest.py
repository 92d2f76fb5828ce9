import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))  # tests/analytic.py

FIXTURES = os.path.join(os.path.dirname(__file__), "fixtures")
PUBLISHED = os.path.join(FIXTURES, "cornell_box_moving.xml")


@pytest.fixture(autouse=True)
def llvm_variant():
    """Every test starts (and ends) with the LLVM RGB variant set."""
    import dopplertof

    dopplertof.set_variant("llvm_ad_rgb")
    yield
    import mitsuba as mi

    if mi.variant() != "llvm_ad_rgb":
        dopplertof.set_variant("llvm_ad_rgb")
