"""``roverops bench vo``: the MER visual odometry measured on rendered Navcam pairs, and what
the ground builds around it (``bench.vo.suite`` puts the parts together; ``bench.vo.courses``
has the drives at MER's 256 px, ``bench.vo.baseline`` the OpenCV baseline beside them)."""

from bench.vo.suite import bench_vo

__all__ = ["bench_vo"]
