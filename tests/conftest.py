"""Suite-wide settings that must be in place before any test module imports its libraries."""

import os

# Every Ray process the suite starts (a local instance, ray.cluster_utils' multi-node clusters, and the
# train-foam subprocesses that join them) binds and connects on the loopback interface only. On Linux,
# Ray picks the host's outward-facing address unless this flag, read once when Ray is imported, says
# "no multi-node `ray start`" (the suite's clusters are built by cluster_utils, which it does not affect).
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
