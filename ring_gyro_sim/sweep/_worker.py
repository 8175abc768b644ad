# Copyright 2026 ring_gyro_sim developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Dask preload of the local cluster's workers: Ctrl-C is the client's.

A Ctrl-C in a terminal reaches every process of the group: the workers of a LocalCluster
would each die with a KeyboardInterrupt traceback in the middle of a point. They ignore
SIGINT instead; the client catches it, keeps what is stored and closes the cluster, which
stops them.
"""

import signal
import threading


def dask_setup(worker) -> None:
    """Ignore SIGINT in this worker process (called by Dask when the worker starts)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
