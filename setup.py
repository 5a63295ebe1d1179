from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'projection_server'


def tree(src, dest_root):
    """data_files entries that install the tree under src into share/<pkg>/dest_root."""
    entries = []
    for dirpath, _, filenames in os.walk(src):
        files = [os.path.join(dirpath, f) for f in filenames]
        if files:
            rel = os.path.relpath(dirpath, src)
            entries.append((os.path.normpath(os.path.join(dest_root, rel)), files))
    return entries


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={'projection_server.simulation.robots': ['assets/*.urdf', 'assets/*.yaml'],
                  'projection_server.simulation.objects': ['assets/*.obj', 'assets/*.stl',
                                                           'assets/*.urdf'],
                  'projection_server.workers': ['*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*')),
        *tree('prolog', 'share/' + package_name + '/prolog'),
    ],
    install_requires=['setuptools', 'numpy', 'pyyaml', 'pybullet', 'rosbags', 'tqdm'],
    zip_safe=True,
    maintainer='projection_server maintainers',
    maintainer_email='maintainers@projection-server.org',
    description='ROS 2 Prolog query service with simulation-based temporal projection.',
    license='BSD-3-Clause',
    entry_points={
        'console_scripts': [
            'projection_server = projection_server.service.node:main',
            'prolog_query = projection_server.client.cli:main',
            'projection_reproduce = projection_server.reproduce.__main__:main',
            'projection_render = projection_server.render.cli:main',
            'projection_standin_robot = projection_server.standin.node:main',
        ],
    },
)
