from setuptools import find_packages, setup

package_name = 'saliency_node'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['templates/manifest.yaml', 'templates/*.png']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=('Language-guided template matching: utterances into saliency images '
                 '(kept objects sharp, the rest blurred).'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'saliency_node = saliency_node.node:main',
            'saliency_make_templates = saliency_node.make_templates:main',
            'saliency_figure = saliency_node.figure:main',
        ],
    },
)
