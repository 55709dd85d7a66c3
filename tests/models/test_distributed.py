"""Process-group helpers of a distributed run, in one process: a gloo group of world size 1."""

import torch.distributed as dist

from models.distributed import end_process_group, gather_objects, world_size


def test_end_process_group_destroys_the_group_and_is_a_no_op_without_one(tmp_path) -> None:
    end_process_group()  # no group: nothing happens
    assert not dist.is_initialized() and world_size() == 1
    dist.init_process_group("gloo", init_method=f"file://{tmp_path / 'store'}", rank=0, world_size=1)
    try:
        assert dist.is_initialized() and gather_objects({"a": 1}) == [{"a": 1}]
    finally:
        end_process_group()
    assert not dist.is_initialized() and world_size() == 1
