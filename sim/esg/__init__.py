"""Strapdown electrically suspended gyro laboratory of report 004 (docs/esg.md)."""

from sim.esg.processor import LineCounts, ProcessorSettings, SignalSpec
from sim.esg.world import EsgParams, EsgWorld

__all__ = ["EsgParams", "EsgWorld", "LineCounts", "ProcessorSettings", "SignalSpec"]
