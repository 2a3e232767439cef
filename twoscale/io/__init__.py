"""Reading scenes and writing results (files live here, never in the solvers).

``scene_file``: TOML scene reader/validator; ``result_json``: result.json writer.
"""

from .scene_file import SceneError, read_scene, scene_from_dict, scene_to_dict
from .result_json import result_to_dict, write_result

__all__ = ["SceneError", "read_scene", "scene_from_dict", "scene_to_dict", "result_to_dict", "write_result"]
