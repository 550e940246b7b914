"""Reading and writing calibration data and cameras: CSV points, JSON, OpenCV and ROS YAML."""

from calib.io.camera_files import load_camera, save_camera
from calib.io.points_csv import PointsFileError, read_points_csv, write_points_csv

__all__ = ["PointsFileError", "load_camera", "read_points_csv", "save_camera", "write_points_csv"]
