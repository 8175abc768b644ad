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

"""ament_python setup of ring_gyro_sim (rclpy and message packages come from ROS, not pip)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'ring_gyro_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'benchmarks']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'numba', 'mcap', 'PyYAML', 'zstandard',
                      'lz4', 'tqdm', 'allantools'],
    # `ring_gyro sweep` (ring_gyro_sim/sweep): imported only when a sweep runs.
    extras_require={'plots': ['matplotlib'],
                    'sweep': ['dask[distributed]', 'xarray', 'netCDF4', 'matplotlib']},
    zip_safe=True,
    maintainer='ring_gyro_sim developers',
    maintainer_email='dev@ring-gyro-sim.invalid',
    description='Emulator of a capacitive MEMS vibrating-ring gyroscope under severe shock.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'ring_gyro_node = ring_gyro_sim.ros.node:main',
            'ring_gyro = ring_gyro_sim.cli:main',
        ],
    },
)
