from setuptools import find_packages, setup

package_name = 'session_bag'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=('Every teaching session as a rosbag2 bag (MCAP storage): the recorder node, '
                 'and reading, checking and repairing a bag from Python.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'session_recorder = session_bag.node:main',
            'attention_bag = session_bag.cli:main',
        ],
    },
)
