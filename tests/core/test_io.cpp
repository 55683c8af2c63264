// Mesh files: round trips, refusing to clobber, clear errors on bad input, and
// the write-to-temporary-then-rename guarantee.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>

#include "isohex/core/AtomicFile.hpp"
#include "isohex/core/Error.hpp"
#include "isohex/core/MeshIO.hpp"
#include "tools/io_test_meshes.hpp"

namespace fs = std::filesystem;
using namespace isohex;

namespace {

// A fresh folder per test, removed afterwards.
class IoTest : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        dir_ = fs::temp_directory_path() / ("isohex_io_" + std::string(info->name()) + "_" +
                                            std::to_string(std::random_device{}()));
        fs::create_directories(dir_);
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string file(const std::string& name) const { return (dir_ / name).string(); }

    // Names of the files in the folder (to spot leftover temporaries).
    std::vector<std::string> listing() const {
        std::vector<std::string> names;
        for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
        std::sort(names.begin(), names.end());
        return names;
    }

    fs::path dir_;
};

std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

void spit(const std::string& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary);
    out << text;
}

// The Error io::read throws for `path`; fails the test if it does not throw.
std::string readError(const std::string& path) {
    try {
        io::read(path);
    } catch (const Error& e) {
        return e.what();
    }
    ADD_FAILURE() << "reading " << path << " did not throw";
    return {};
}

void expectOneLineNaming(const std::string& message, const std::string& path) {
    EXPECT_NE(message.find(path), std::string::npos) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_LT(message.size(), 400u) << message;
}

void expectSameGeometryAndMaterials(const HexMesh& a, const HexMesh& b) {
    ASSERT_EQ(a.nodeCount(), b.nodeCount());
    ASSERT_EQ(a.hexCount(), b.hexCount());
    for (std::size_t i = 0; i < a.nodeCount(); ++i) EXPECT_EQ(a.nodes[i], b.nodes[i]) << "node " << i;
    for (std::size_t h = 0; h < a.hexCount(); ++h) {
        EXPECT_EQ(a.hexes[h], b.hexes[h]) << "hex " << h;
        EXPECT_EQ(a.material[h], b.material[h]) << "hex " << h;
    }
}

HexMesh sampleMesh() {
    HexMesh m = iotest::makeTwoMaterialBlock(4, 3, 2, 0.5);
    // Coordinates that need all 17 digits to survive a text round trip.
    m.nodes[5][0] += 1.0 / 3.0;
    m.nodes[7][2] -= 1e-13;
    return m;
}

}  // namespace

TEST(IoFormat, ExtensionChoosesFormat) {
    EXPECT_EQ(io::formatFromPath("a/b.vtu"), io::Format::Vtu);
    EXPECT_EQ(io::formatFromPath("b.MSH"), io::Format::Msh);
    EXPECT_EQ(io::formatFromPath("b.exo"), io::Format::Exodus);
    EXPECT_EQ(io::formatFromPath("b.e"), io::Format::Exodus);
    EXPECT_EQ(io::formatFromPath("b.inp"), io::Format::Abaqus);
    EXPECT_EQ(io::formatFromPath("b.mesh"), io::Format::Medit);
    EXPECT_TRUE(io::canRead(io::Format::Vtu));
    EXPECT_TRUE(io::canRead(io::Format::Msh));
    EXPECT_FALSE(io::canRead(io::Format::Abaqus));
}

TEST(IoFormat, UnknownExtensionListsTheSupportedOnes) {
    try {
        io::formatFromPath("mesh.stl");
        FAIL() << "no error";
    } catch (const Error& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("mesh.stl"), std::string::npos) << m;
        for (const char* ext : {".vtu", ".msh", ".exo", ".inp", ".mesh"}) EXPECT_NE(m.find(ext), std::string::npos) << m;
    }
}

TEST_F(IoTest, VtuRoundTripKeepsEverything) {
    const HexMesh mesh = sampleMesh();
    io::write(mesh, file("m.vtu"));
    const HexMesh back = io::read(file("m.vtu"));
    expectSameGeometryAndMaterials(mesh, back);
    EXPECT_EQ(back.nodeClass, mesh.nodeClass);
    EXPECT_EQ(back.surfaces, mesh.surfaces);
}

TEST_F(IoTest, VtuTakesGivenScaledJacobiansAndChecksTheirCount) {
    const HexMesh mesh = sampleMesh();
    io::WriteOptions opt;
    opt.scaledJacobian.assign(mesh.hexCount(), 0.5);
    io::write(mesh, file("sj.vtu"), opt);
    EXPECT_NE(slurp(file("sj.vtu")).find("scaled_jacobian"), std::string::npos);
    opt.scaledJacobian.pop_back();
    EXPECT_THROW(io::write(mesh, file("sj2.vtu"), opt), Error);
    EXPECT_FALSE(fs::exists(file("sj2.vtu")));
}

TEST_F(IoTest, MshRoundTripKeepsGeometryConnectivityAndMaterials) {
    const HexMesh mesh = sampleMesh();
    io::write(mesh, file("m.msh"));
    EXPECT_EQ(slurp(file("m.msh")).rfind("$MeshFormat\n4.1 0 8", 0), 0u);
    const HexMesh back = io::read(file("m.msh"));
    expectSameGeometryAndMaterials(mesh, back);
}

TEST_F(IoTest, MshRoundTripKeepsMaterialZeroAndRefusesNegativeOnReading) {
    const HexMesh mesh = iotest::makeTwoMaterialBlock(2, 2, 2, 1.0, 0, 3);
    io::write(mesh, file("z.msh"));
    expectSameGeometryAndMaterials(mesh, io::read(file("z.msh")));
    // A negative id would be taken for the outside by the surface naming
    // (SurfaceTag::outside < 0), so reading refuses it with a clear error.
    io::write(iotest::makeTwoMaterialBlock(2, 2, 2, 1.0, 0, -3), file("n.msh"));
    try {
        io::read(file("n.msh"));
        FAIL() << "a negative material id was accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("material id -3"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("n.msh"), std::string::npos) << e.what();
    }
}

TEST_F(IoTest, MshNamesMaterialAndSurfaceGroups) {
    io::write(sampleMesh(), file("names.msh"));
    const std::string text = slurp(file("names.msh"));
    for (const char* name : {"\"material_1\"", "\"material_2\"", "\"boundary_m1\"", "\"outer_skin_of_material_two\"",
                             "\"interface_m1_m2\""})
        EXPECT_NE(text.find(name), std::string::npos) << name;
}

TEST_F(IoTest, RepeatedGmshUseInOneProcessWorks) {
    const HexMesh mesh = sampleMesh();
    for (int i = 0; i < 3; ++i) {
        const std::string p = file("r" + std::to_string(i) + ".msh");
        io::write(mesh, p);
        expectSameGeometryAndMaterials(mesh, io::read(p));
    }
}

TEST_F(IoTest, WritesEveryFormat) {
    const HexMesh mesh = sampleMesh();
    for (const std::string& ext : io::writableExtensions()) {
        const std::string p = file("all" + ext);
        ASSERT_NO_THROW(io::write(mesh, p)) << ext;
        EXPECT_GT(fs::file_size(p), 100u) << ext;
    }
    EXPECT_EQ(slurp(file("all.exo")).substr(0, 3), "CDF");  // netCDF classic
    const std::string inp = slurp(file("all.inp"));
    EXPECT_NE(inp.find("*ELEMENT, TYPE=C3D8, ELSET=MAT_1\n"), std::string::npos);
    EXPECT_NE(inp.find("*ELEMENT, TYPE=C3D8, ELSET=MAT_2\n"), std::string::npos);
    EXPECT_NE(inp.find("*SURFACE, TYPE=ELEMENT, NAME=boundary_m1\n"), std::string::npos);
    EXPECT_NE(inp.find("*SURFACE, TYPE=ELEMENT, NAME=interface_m1_m2\n"), std::string::npos);
    const std::string medit = slurp(file("all.mesh"));
    EXPECT_EQ(medit.rfind("MeshVersionFormatted 2\n", 0), 0u);
    EXPECT_NE(medit.find("\nHexahedra\n24\n"), std::string::npos);
    // 4x3x2 block: 2*(12+8+6) = 52 boundary quads plus 3*2 interface quads.
    EXPECT_NE(medit.find("\nQuadrilaterals\n58\n"), std::string::npos);
}

TEST_F(IoTest, WritesAndReadsFromSeveralThreadsAtOnce) {
    // VTK's output window, Gmsh's model and libexodusII's options are global
    // state; the writers serialise around them.
    const HexMesh mesh = sampleMesh();
    std::vector<std::thread> threads;
    std::atomic<int> failures{0};
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&, t] {
            try {
                for (const std::string& ext : io::writableExtensions()) {
                    const std::string p = file("t" + std::to_string(t) + ext);
                    io::write(mesh, p);
                    if (io::canRead(io::formatFromPath(p)) && io::read(p).hexes != mesh.hexes) ++failures;
                }
            } catch (...) {
                ++failures;
            }
        });
    for (auto& th : threads) th.join();
    EXPECT_EQ(failures.load(), 0);
}

TEST_F(IoTest, RefusesToClobberAnExistingFile) {
    const HexMesh mesh = sampleMesh();
    for (const std::string& ext : io::writableExtensions()) {
        const std::string p = file("keep" + ext);
        spit(p, "precious");
        try {
            io::write(mesh, p);
            ADD_FAILURE() << ext << ": overwrote an existing file";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("exists"), std::string::npos) << e.what();
        }
        EXPECT_EQ(slurp(p), "precious") << ext;
        io::WriteOptions force;
        force.overwrite = true;
        io::write(mesh, p, force);
        EXPECT_NE(slurp(p), "precious") << ext;
    }
    EXPECT_EQ(listing().size(), io::writableExtensions().size());  // no temporaries left
}

TEST_F(IoTest, InjectedWriteFailureKeepsTheOldFileAndLeavesNoTemporary) {
    const std::string p = file("old.vtu");
    io::write(sampleMesh(), p);
    const std::string before = slurp(p);
    std::string tmpSeen;
    EXPECT_THROW(io::writeAtomically(p, true,
                                     [&](const std::string& tmp) {
                                         tmpSeen = tmp;
                                         spit(tmp, before.substr(0, before.size() / 2));  // half-written
                                         throw Error("injected failure");
                                     }),
                 Error);
    EXPECT_EQ(fs::path(tmpSeen).parent_path(), fs::path(p).parent_path());
    EXPECT_FALSE(fs::exists(tmpSeen));
    EXPECT_EQ(slurp(p), before);
    EXPECT_EQ(listing(), std::vector<std::string>{"old.vtu"});
}

TEST_F(IoTest, FailedWriterKeepsTheOldFile) {
    for (const std::string& ext : io::writableExtensions()) {
        const std::string p = file("old" + ext);
        spit(p, "old contents");
        HexMesh bad = sampleMesh();
        bad.hexes[3][2] = 100000;  // out of range
        io::WriteOptions force;
        force.overwrite = true;
        EXPECT_THROW(io::write(bad, p, force), Error) << ext;
        EXPECT_EQ(slurp(p), "old contents") << ext;
    }
    EXPECT_EQ(listing().size(), io::writableExtensions().size());
}

TEST_F(IoTest, EmptyMeshIsRefusedInEveryFormat) {
    HexMesh empty;
    empty.addNode({0, 0, 0});
    for (const std::string& ext : io::writableExtensions()) {
        try {
            io::write(empty, file("empty" + ext));
            ADD_FAILURE() << ext << ": wrote a mesh without hexahedra";
        } catch (const Error& e) {
            expectOneLineNaming(e.what(), file("empty" + ext));
        }
    }
    EXPECT_TRUE(listing().empty());
}

TEST_F(IoTest, WriteIntoMissingFolderIsAClearError) {
    try {
        io::write(sampleMesh(), file("no/such/folder/m.vtu"));
        FAIL() << "no error";
    } catch (const Error& e) {
        expectOneLineNaming(e.what(), file("no/such/folder/m.vtu"));
    }
}

TEST_F(IoTest, MissingFileIsAClearError) {
    for (const char* name : {"none.vtu", "none.msh"}) {
        const std::string m = readError(file(name));
        expectOneLineNaming(m, file(name));
        EXPECT_NE(m.find("no such file"), std::string::npos) << m;
    }
}

TEST_F(IoTest, WriteOnlyFormatsCannotBeRead) {
    io::write(sampleMesh(), file("w.inp"));
    const std::string m = readError(file("w.inp"));
    expectOneLineNaming(m, file("w.inp"));
    EXPECT_NE(m.find(".vtu"), std::string::npos) << m;
}

TEST_F(IoTest, GarbageAndEmptyFilesAreClearErrors) {
    std::mt19937 rng(7);
    std::string noise(4096, '\0');
    for (char& c : noise) c = static_cast<char>(rng() & 0xff);
    for (const char* ext : {".vtu", ".msh"}) {
        const std::string text = file(std::string("text") + ext);
        const std::string binary = file(std::string("noise") + ext);
        const std::string empty = file(std::string("empty") + ext);
        spit(text, "this is not a mesh\nat all\n");
        spit(binary, noise);
        spit(empty, "");
        for (const auto& p : {text, binary, empty}) expectOneLineNaming(readError(p), p);
    }
    EXPECT_NE(readError(file("text.msh")).find("$MeshFormat"), std::string::npos);
}

TEST_F(IoTest, TruncatedFilesAreClearErrors) {
    const HexMesh mesh = sampleMesh();
    for (const char* ext : {".vtu", ".msh"}) {
        const std::string whole = file(std::string("whole") + ext);
        io::write(mesh, whole);
        const std::string text = slurp(whole);
        for (double fraction : {0.1, 0.5, 0.9, 0.99}) {
            const std::string cut = file("cut" + std::to_string(static_cast<int>(fraction * 100)) + ext);
            spit(cut, text.substr(0, static_cast<std::size_t>(text.size() * fraction)));
            expectOneLineNaming(readError(cut), cut);
        }
    }
}

TEST_F(IoTest, VtuWhoseHeaderDisagreesWithItsDataIsAClearError) {
    io::write(sampleMesh(), file("good.vtu"));
    const std::string text = slurp(file("good.vtu"));
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"NumberOfCells=\"24\"", "NumberOfCells=\"99\""},
                                   {"NumberOfPoints=\"60\"", "NumberOfPoints=\"61\""}}) {
        const auto at = text.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        std::string bad = text;
        bad.replace(at, from.size(), to);
        const std::string p = file("bad.vtu");
        spit(p, bad);
        const std::string m = readError(p);
        expectOneLineNaming(m, p);
        EXPECT_NE(m.find("damaged"), std::string::npos) << m;
    }
}

TEST_F(IoTest, VtuWithNonHexCellsIsRejectedClearly) {
    const std::string p = file("tet.vtu");
    spit(p, R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
  <UnstructuredGrid>
    <Piece NumberOfPoints="4" NumberOfCells="1">
      <Points>
        <DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 0 1 0 0 0 1</DataArray>
      </Points>
      <Cells>
        <DataArray type="Int64" Name="connectivity" format="ascii">0 1 2 3</DataArray>
        <DataArray type="Int64" Name="offsets" format="ascii">4</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">10</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
)");
    const std::string m = readError(p);
    expectOneLineNaming(m, p);
    EXPECT_NE(m.find("hexahedra"), std::string::npos) << m;
    EXPECT_NE(m.find("Tetra"), std::string::npos) << m;
}

TEST_F(IoTest, VtuWithoutMaterialGetsMaterialOne) {
    const std::string p = file("plain.vtu");
    spit(p, R"(<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="8" NumberOfCells="1">
      <Points>
        <DataArray type="Float32" NumberOfComponents="3" format="ascii">0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1</DataArray>
      </Points>
      <Cells>
        <DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3 4 5 6 7</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">8</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">12</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
)");
    const HexMesh m = io::read(p);
    ASSERT_EQ(m.hexCount(), 1u);
    EXPECT_EQ(m.material[0], 1);
    EXPECT_EQ(m.hexes[0], (Hex{0, 1, 2, 3, 4, 5, 6, 7}));
    EXPECT_EQ(m.nodes[6], (Vec3{1, 1, 1}));
    EXPECT_EQ(m.nodeClass[0].kind, NodeKind::Interior);
}

TEST_F(IoTest, MshWithoutHexesIsRejectedClearly) {
    const std::string p = file("tet.msh");
    spit(p, R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Entities
0 0 0 1
1 0 0 0 1 1 1 0 0
$EndEntities
$Nodes
1 4 1 4
3 1 0 4
1
2
3
4
0 0 0
1 0 0
0 1 0
0 0 1
$EndNodes
$Elements
1 1 1 1
3 1 4 1
1 1 2 3 4
$EndElements
)");
    const std::string m = readError(p);
    expectOneLineNaming(m, p);
    EXPECT_NE(m.find("8-node hexahedra"), std::string::npos) << m;
}
