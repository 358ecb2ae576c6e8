import numpy as np

def pair_positions(
    head: np.ndarray,
    t: np.ndarray,
    ch: np.ndarray,
    subsecond: np.ndarray,
    order: np.ndarray | None,
    head_step_s: np.ndarray | None,
    fine_window_ns: int,
    coarse_window_ns: int,
    sys1: int,
    sys2: int,
    /,
) -> tuple[int, bytearray, bytearray, bytearray, bytearray] | None: ...
