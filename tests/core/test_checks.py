"""core.checks: each check passes good input through and names the argument in its InputError."""

import pytest
import torch

from core.checks import check_device, check_positive, check_same_dtype, check_tensor
from core.errors import InputError


def test_check_tensor_accepts_and_returns_matching_tensors() -> None:
    x = torch.zeros(2, 5, 3, 4)
    assert check_tensor(x, "P", shape=(None, None, 3, 4), floating=True) is x
    assert check_tensor(torch.zeros(3, 1, 1), "z", min_ndim=3) is not None


@pytest.mark.parametrize(("value", "kwargs", "message"), [
    ([1.0], {}, "P must be a torch.Tensor, got list"),
    (torch.zeros(2, 3, 4), {"shape": (None, None, 3, 4)}, r"P must have shape \(\*, \*, 3, 4\), got \(2, 3, 4\)"),
    (torch.zeros(2, 5, 3, 3), {"shape": (None, None, 3, 4)}, r"got \(2, 5, 3, 3\)"),
    (torch.zeros(4), {"min_ndim": 2}, "P needs at least 2 axes"),
    (torch.zeros(2, dtype=torch.int64), {"floating": True}, "P must be a real floating tensor, got torch.int64"),
    (torch.zeros(2, dtype=torch.complex64), {"floating": True}, "real floating"),
])
def test_check_tensor_names_the_argument(value, kwargs, message) -> None:
    with pytest.raises(InputError, match=message):
        check_tensor(value, "P", **kwargs)


def test_same_dtype_and_positive() -> None:
    a, b = torch.zeros(1), torch.zeros(1, dtype=torch.float64)
    assert check_same_dtype(("a", a), ("c", a.clone())) == torch.float32
    with pytest.raises(InputError, match="a, b must share one dtype, got a torch.float32 and b torch.float64"):
        check_same_dtype(("a", a), ("b", b))
    assert check_positive(0.5, "sigma") == 0.5
    for bad in (0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(InputError, match="sigma must be positive"):
            check_positive(bad, "sigma")


def test_input_error_is_a_value_error() -> None:
    """Callers that catch ValueError (argparse-style code, numpy users) still catch every input error."""
    assert issubclass(InputError, ValueError)


def test_check_device_accepts_the_cpu_and_names_a_bad_device():
    assert check_device("cpu") == torch.device("cpu")
    with pytest.raises(InputError, match="--device 'gpu0' is not a torch device"):
        check_device("gpu0", "--device")
    with pytest.raises(InputError, match="--device 'meta': only cpu and cuda devices are supported"):
        check_device("meta", "--device")


@pytest.mark.skipif(torch.cuda.is_available(), reason="checks the refusal where CUDA is absent")
def test_check_device_refuses_cuda_without_cuda():
    with pytest.raises(InputError, match="device 'cuda:0' requested but CUDA is not available"):
        check_device("cuda:0")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")
def test_check_device_refuses_a_cuda_index_beyond_the_devices():
    assert check_device("cuda:0").type == "cuda"
    with pytest.raises(InputError, match="CUDA devices exist"):
        check_device(f"cuda:{torch.cuda.device_count()}")
