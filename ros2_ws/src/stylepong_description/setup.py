from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'stylepong_description'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='The one UR5 + table-tennis paddle model, loaded by Pinocchio and MuJoCo alike.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [],
    },
)
