"""``roverops bench vo``: the MER visual odometry measured on rendered Navcam pairs
(``bench.vo.courses`` has the drives and the figures; ``bench.vo.baseline`` the OpenCV
baseline beside it)."""

from bench.vo.courses import bench_vo

__all__ = ["bench_vo"]
