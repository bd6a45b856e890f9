"""pinquad.discovery: find, name, fit and refit what the identified model leaves
unexplained (see ``pinquad.discovery.discover`` and docs/architecture.md)."""

from pinquad.discovery.discover import base_heldout_rms, discover
from pinquad.discovery.refit import corrected_observations, refit
from pinquad.discovery.result import DiscoveryConfig, DiscoveryResult

__all__ = ["DiscoveryConfig", "DiscoveryResult", "base_heldout_rms", "corrected_observations",
           "discover", "refit"]
