"""Types of the extension module under ``strahl`` (python/src/lib.rs). Its functions take
flat contiguous arrays; ``strahl/__init__.py`` checks and shapes them."""

from typing import Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

INVALID_ID: int
MAX_TRIANGLES: int
__version__: str

_Camera = Tuple[Tuple[float, float, float], Tuple[float, float, float], Tuple[float, float, float], float]

class Scene:
    def __init__(self, device: str = "auto", precision: str = "f32") -> None: ...
    @staticmethod
    def from_file(path: str, device: str = "auto", precision: str = "f32") -> "Scene": ...
    def device(self) -> str: ...
    def add_triangles(
        self, vertices: npt.NDArray[np.floating], nvertices: int, triangles: npt.NDArray[np.int64], ntriangles: int
    ) -> int: ...
    def add_spheres(self, centers: npt.NDArray[np.floating], radii: npt.NDArray[np.floating], n: int) -> int: ...
    def add_cylinders(
        self,
        p0: npt.NDArray[np.floating],
        p1: npt.NDArray[np.floating],
        radii: npt.NDArray[np.floating],
        n: int,
    ) -> int: ...
    def cast_rays(self, rays: npt.NDArray[np.floating], lead: List[int]) -> Dict[str, np.ndarray]: ...
    def test_occlusions(
        self, rays: npt.NDArray[np.floating], lead: List[int], tnear: float, tfar: float
    ) -> npt.NDArray[np.bool_]: ...
    def count_intersections(self, rays: npt.NDArray[np.floating], lead: List[int]) -> npt.NDArray[np.uint32]: ...
    def list_intersections(self, rays: npt.NDArray[np.floating], lead: List[int]) -> Dict[str, np.ndarray]: ...
    def compute_closest_points(self, points: npt.NDArray[np.floating], lead: List[int]) -> Dict[str, np.ndarray]: ...
    def compute_distance(self, points: npt.NDArray[np.floating], lead: List[int], signed: bool) -> np.ndarray: ...
    def render(
        self,
        mode: str,
        spp: int,
        width: Optional[int],
        height: Optional[int],
        max_depth: Optional[int],
        seed: int,
        device: str,
        camera: Optional[_Camera],
        denoise: bool,
    ) -> Tuple[npt.NDArray[np.float32], str, int, int]: ...
