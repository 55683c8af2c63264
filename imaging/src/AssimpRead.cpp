// A triangle surface read with Assimp, corners welded where their coordinates
// are equal (the plugin libisohex_assimp.so, ReaderPlugins.hpp). Surface.cpp
// checks the file's layout before and the surface after.
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include "ReaderPlugins.hpp"
#include "isohex/core/Error.hpp"

namespace isohex::imaging::detail {
namespace {

struct Vec3Hash {
    std::size_t operator()(const Vec3& p) const {
        std::size_t h = 0;
        for (double c : p) h = h * 1000003u ^ std::hash<double>()(c == 0.0 ? 0.0 : c);  // -0 == +0
        return h;
    }
};

void appendNode(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent,
                TriangleSurface& out, std::unordered_map<Vec3, std::int32_t, Vec3Hash>& weld) {
    const aiMatrix4x4 m = parent * node.mTransformation;
    for (unsigned k = 0; k < node.mNumMeshes; ++k) {
        const aiMesh& mesh = *scene.mMeshes[node.mMeshes[k]];
        std::vector<std::int32_t> ids(mesh.mNumVertices);
        for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
            const aiVector3D p = m * mesh.mVertices[v];
            const Vec3 q{double(p.x), double(p.y), double(p.z)};
            auto [it, fresh] = weld.emplace(q, std::int32_t(out.vertices.size()));
            if (fresh) out.vertices.push_back(q);
            ids[v] = it->second;
        }
        for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
            const aiFace& face = mesh.mFaces[f];
            if (face.mNumIndices != 3) continue;  // points and lines carry no volume
            const std::array<std::int32_t, 3> t{ids[face.mIndices[0]], ids[face.mIndices[1]],
                                                ids[face.mIndices[2]]};
            if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
                ++out.droppedDegenerate;
                continue;
            }
            out.triangles.push_back(t);
        }
    }
    for (unsigned c = 0; c < node.mNumChildren; ++c) appendNode(scene, *node.mChildren[c], m, out, weld);
}

}  // namespace

TriangleSurface readAssimpSurface(const std::string& file, const std::string* offText) {
    Assimp::Importer importer;
    // Normals and texture coordinates would keep coincident corners apart.
    // Corners are welded by appendNode where their coordinates are equal;
    // Assimp's own aiProcess_JoinIdenticalVertices also joins corners closer
    // than an absolute 1e-5, which welded a sphere of radius 1e-9 into a
    // non-manifold knot of triangles.
    importer.SetPropertyInteger(AI_CONFIG_PP_RVC_FLAGS,
                                aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS |
                                    aiComponent_COLORS | aiComponent_TEXCOORDS);
    const unsigned flags = aiProcess_RemoveComponent | aiProcess_Triangulate;
    const aiScene* scene = offText ? importer.ReadFileFromMemory(offText->data(), offText->size(), flags, "off")
                                   : importer.ReadFile(file, flags);
    if (!scene || !scene->mRootNode) {
        throw Error(file + ": cannot be read as a triangle surface (" + boundedMessage(importer.GetErrorString()) +
                    "). Supported: .stl (ascii/binary), .obj, .ply, .off; check the file is complete.");
    }
    TriangleSurface s;
    s.source = file;
    std::unordered_map<Vec3, std::int32_t, Vec3Hash> weld;
    appendNode(*scene, *scene->mRootNode, aiMatrix4x4(), s, weld);
    return s;
}

}  // namespace isohex::imaging::detail
