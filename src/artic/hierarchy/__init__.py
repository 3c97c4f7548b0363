"""Chapter 4: part segmentation, part graphs, GNN labelling, kinematic trees and their metrics."""
