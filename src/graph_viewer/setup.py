from setuptools import find_packages, setup

package_name = 'graph_viewer'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['layouts/*.json']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=('The graph live in Foxglove: a Foxglove WebSocket bridge of every topic, with '
                 'plottable metrics, H and status, and a layout for live sessions and bags.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'graph_viewer = graph_viewer.node:main',
            'graph_viewer_layout = graph_viewer.layout:main',
            'graph_viewer_plots = graph_viewer.bag_plots:main',
        ],
    },
)
