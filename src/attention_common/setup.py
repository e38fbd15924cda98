from setuptools import find_packages, setup

package_name = 'attention_common'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['data/*.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description='Shared pieces of the language-attention TAMER graph: topic names, QoS, '
                'Image/numpy conversion, Joy/ALE actions, stamps, network isolation.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
        ],
    },
)
