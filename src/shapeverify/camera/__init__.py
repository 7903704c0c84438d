"""Perspective geometry: pinhole camera, exact ray–CAD intersection, small-motion depth update (Paper IV)."""

from shapeverify.camera.intersect import RayHits, RayScene, intersect_rays
from shapeverify.camera.pinhole import PinholeCamera
from shapeverify.camera.view import View, depth_map, make_view, render, render_images

__all__ = ["PinholeCamera", "RayHits", "RayScene", "View", "depth_map", "intersect_rays", "make_view",
           "render", "render_images"]
