"""Simulation: a virtual optical scanner with realistic defects and the truth of every point."""
from .hologram import (Hologram, OffAxis, dual_wavelength_holograms, grooved_plate, rough_surface,
                       simulate_hologram)
from .scanner import (BLOB, DENT, INLIER, LABELS, OUTLIER, Accuracy, ScanEffects, VirtualScan,
                      random_motion,
                      virtual_scan)
from .fringes import CameraResponse, FringeImages, demo_scene, fringe_images
from .stereo_demo import simulate_and_measure_demo

__all__ = ["virtual_scan", "VirtualScan", "Accuracy", "random_motion", "INLIER", "OUTLIER",
           "BLOB", "DENT", "LABELS",
           "fringe_images", "FringeImages", "demo_scene", "ScanEffects", "CameraResponse",
           "OffAxis", "simulate_and_measure_demo"]
