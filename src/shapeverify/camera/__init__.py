"""Perspective geometry: pinhole camera, exact ray–CAD intersection, small-motion depth update (Paper IV)."""

from shapeverify.camera.intersect import RayHits, RayScene, intersect_rays
from shapeverify.camera.pinhole import PinholeCamera
from shapeverify.camera.view import View, depth_map, make_view, render, render_images
from shapeverify.camera.rig import (Device, Pattern, Rig, RigFormatError, RigProjector, load_rig,
                                   look_at_rig, save_rig)
from shapeverify.camera.calibration import Calibration, calibrate, render_chessboard
from shapeverify.camera.stereo import StereoMatching, StereoScan, measure

__all__ = ["PinholeCamera", "RayHits", "RayScene", "View", "depth_map", "intersect_rays", "make_view",
           "RigProjector", "StereoMatching",
           "render", "render_images",
           "Device", "Pattern", "Rig", "RigFormatError", "load_rig", "save_rig", "look_at_rig",
           "Calibration", "calibrate", "render_chessboard", "StereoScan", "measure"]
