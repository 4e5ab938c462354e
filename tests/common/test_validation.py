"""The shared validation's messages name the bad value as a user wrote it."""

import numpy as np
import pytest

from adcs_common.exceptions import InvalidValueError
from adcs_common.validation import as_finite_array, as_finite_scalar


@pytest.mark.parametrize("value, text", [
    (float("nan"), "got nan"), (np.inf, "got inf"), (np.float64(-np.inf),
                                                      "got -inf")])
def test_a_non_finite_scalar_is_named_plainly(value, text):
    with pytest.raises(InvalidValueError) as err:
        as_finite_scalar(value, "dt")
    assert str(err.value) == f"dt must be finite, {text}"


def test_a_non_finite_array_is_shown_short():
    with pytest.raises(InvalidValueError,
                       match=r"^w must be finite, got \[ 1\. nan\]$"):
        as_finite_array([1.0, np.nan], "w", (2,))
    with pytest.raises(InvalidValueError) as err:
        as_finite_array(np.r_[np.arange(1000.0), np.nan], "big")
    assert "..." in str(err.value) and len(str(err.value)) < 120
