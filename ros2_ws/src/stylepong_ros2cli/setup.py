from setuptools import find_packages, setup

PACKAGE = 'stylepong_ros2cli'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='A small ros2 command for ROS 2 Jazzy from PyPI wheels, which lack ros2cli.',
    license='Apache-2.0',
    # No console script: the command is `ros2` itself, which tools/setup.sh puts into the venv (tools/ros2).
    entry_points={'console_scripts': []},
)
