// SPDX-License-Identifier: Apache-2.0
// White-box tests of the atomic file writer (src/detail/AtomicFile.h): which outputs it
// refuses, /dev/null written through, links followed, the temporary-file naming, stale
// temporary files, and interruption (abortWrites, removeLiveTemporaryFiles).
#include "TestUtil.h"

#include "detail/AtomicFile.h"

#include <levelforge/core/Exceptions.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

namespace fs = std::filesystem;
using levelforge::InterruptedError;
using levelforge::IoError;
using levelforge::detail::AtomicFile;
using levelforge_test::scratchDir;

namespace {

std::vector<std::string> listDir(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
    std::sort(names.begin(), names.end());
    return names;
}

std::string readText(const fs::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void writeAll(int fd, const std::string& text)
{
    ASSERT_EQ(::write(fd, text.data(), text.size()), ssize_t(text.size()));
}

/// A PID that no longer exists: a forked child that has exited and been reaped.
long deadPid()
{
    const pid_t child = ::fork();
    if (child == 0) ::_exit(0);
    int status = 0;
    ::waitpid(child, &status, 0);
    return long(child);
}

/// Creates an empty file.
void touch(const fs::path& path) { std::ofstream(path) << ""; }

/// Writes (through the AtomicFile) and commits.
void writeAtomically(const std::string& path, const std::string& text)
{
    AtomicFile file(path, "cannot write '" + path + "'");
    writeAll(file.descriptor(), text);
    file.sync();
    file.commit();
}

/// Clears abortWrites() at the end of a test, whatever happens.
struct AbortGuard
{
    ~AbortGuard() { levelforge::detail::clearAbortedWrites(); }
};

std::string messageOf(const std::string& path)
{
    try {
        AtomicFile file(path, "cannot write '" + path + "'");
    } catch (const IoError& e) {
        return e.what();
    }
    return "(accepted)";
}

} // namespace

TEST(AtomicFile, WritesAtomicallyWithTheDocumentedTemporaryName)
{
    const fs::path dir = scratchDir("atomic_basic");
    const std::string target = (dir / "out.vdb").string();
    {
        AtomicFile file(target, "cannot write 'out.vdb'");
        EXPECT_FALSE(file.writesThrough());
        EXPECT_EQ(file.path(), target);
        EXPECT_EQ(file.targetPath(), target);
        const fs::path tmp(file.tempPath());
        EXPECT_EQ(tmp.parent_path(), dir);
        long pid = 0;
        EXPECT_TRUE(levelforge::detail::parseTemporaryFileName(tmp.filename(), "out.vdb", pid))
            << tmp;
        EXPECT_EQ(pid, long(::getpid()));
        EXPECT_TRUE(fs::is_regular_file(tmp));
        writeAll(file.descriptor(), "hello");
        EXPECT_FALSE(fs::exists(target));
        file.sync();
        file.commit();
        EXPECT_FALSE(fs::exists(tmp));
    }
    EXPECT_EQ(readText(target), "hello");
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.vdb"});

    // Not committed: nothing is left behind and the old file stays.
    {
        AtomicFile file(target, "cannot write 'out.vdb'");
        writeAll(file.descriptor(), "partial");
    }
    EXPECT_EQ(readText(target), "hello");
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.vdb"});
}

TEST(AtomicFile, TemporaryFileNamesParseExactly)
{
    using levelforge::detail::parseTemporaryFileName;
    using levelforge::detail::temporaryFileName;
    const std::string name = temporaryFileName("m.vdb", 1234, 0xdeadbeefcafef00dull);
    EXPECT_EQ(name, ".m.vdb.1234-cafef00d.tmp");
    long pid = 0;
    EXPECT_TRUE(parseTemporaryFileName(name, "m.vdb", pid));
    EXPECT_EQ(pid, 1234);
    for (const char* other : {".m.vdb.1234-cafef00.tmp",    // 7 hex digits
                              ".m.vdb.1234-CAFEF00D.tmp",   // upper case
                              ".m.vdb.12a4-cafef00d.tmp",   // not a PID
                              ".m.vdb.-cafef00d.tmp",       // no PID
                              ".m.vdb.0-cafef00d.tmp",      // PID 0
                              ".m.vdb.1234-cafef00d.tmpx",  // wrong end
                              "m.vdb.1234-cafef00d.tmp",    // not hidden
                              ".x.m.vdb.1234-cafef00d.tmp", // another target
                              ".m.1234-cafef00d.tmp"}) {    // another target
        EXPECT_FALSE(parseTemporaryFileName(other, "m.vdb", pid)) << other;
    }
    // The temporary file of "m.vdb" is not one of "m" nor of "vdb".
    EXPECT_FALSE(parseTemporaryFileName(name, "m", pid));
    EXPECT_FALSE(parseTemporaryFileName(name, "vdb", pid));
}

TEST(AtomicFile, RefusesAFifoWithoutOpeningIt)
{
    const fs::path dir = scratchDir("atomic_fifo");
    const fs::path fifo = dir / "pipe.vdb";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
    // A FIFO without a reader would block an open() for writing: the refusal must come first.
    const std::string msg = messageOf(fifo.string());
    EXPECT_NE(msg.find("'" + fifo.string() + "' is a FIFO"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not a regular file"), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind("cannot write '" + fifo.string() + "'", 0), 0u) << msg;
    struct stat st {};
    ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode));
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"pipe.vdb"});
}

TEST(AtomicFile, RefusesADirectoryASocketAndALinkToThem)
{
    const fs::path dir = scratchDir("atomic_dir");
    const fs::path sub = dir / "sub.vdb";
    fs::create_directory(sub);
    std::string msg = messageOf(sub.string());
    EXPECT_NE(msg.find("'" + sub.string() + "' is a directory, not a regular file"),
              std::string::npos)
        << msg;
    EXPECT_TRUE(fs::is_directory(sub));

    fs::create_symlink("sub.vdb", dir / "link.vdb");
    msg = messageOf((dir / "link.vdb").string());
    EXPECT_NE(msg.find("is a link to"), std::string::npos) << msg;
    EXPECT_NE(msg.find("which is a directory"), std::string::npos) << msg;
    EXPECT_TRUE(fs::is_symlink(dir / "link.vdb"));

    const fs::path sock = dir / "s.vdb";
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    ASSERT_GE(fd, 0);
    sockaddr_un addr {};
    addr.sun_family = AF_UNIX;
    if (sock.string().size() < sizeof(addr.sun_path)) {
        std::strcpy(addr.sun_path, sock.c_str());
        ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
        msg = messageOf(sock.string());
        EXPECT_NE(msg.find("is a socket"), std::string::npos) << msg;
        struct stat st {};
        ASSERT_EQ(::lstat(sock.c_str(), &st), 0);
        EXPECT_TRUE(S_ISSOCK(st.st_mode));
    }
    ::close(fd);
    const std::vector<std::string> names = listDir(dir);
    EXPECT_EQ(std::count_if(names.begin(), names.end(),
                            [](const std::string& n) { return n.find(".tmp") != std::string::npos; }),
              0);
}

TEST(AtomicFile, RefusesACharacterDeviceOtherThanDevNull)
{
    for (const char* device : {"/dev/full", "/dev/zero"}) {
        struct stat before {};
        if (::stat(device, &before) != 0 || !S_ISCHR(before.st_mode)) continue;
        const std::string msg = messageOf(device);
        EXPECT_NE(msg.find(std::string("'") + device + "' is a character device, not a regular file"),
                  std::string::npos)
            << msg;
        struct stat after {};
        ASSERT_EQ(::lstat(device, &after), 0);
        EXPECT_TRUE(S_ISCHR(after.st_mode)) << device << " was replaced";
        EXPECT_EQ(after.st_rdev, before.st_rdev);
    }
}

TEST(AtomicFile, WritesThroughDevNullWithoutReplacingIt)
{
    struct stat before {};
    ASSERT_EQ(::stat("/dev/null", &before), 0);
    ASSERT_TRUE(S_ISCHR(before.st_mode));
    EXPECT_TRUE(levelforge::detail::isNullDevice("/dev/null"));
    const auto devEntries = listDir("/dev");

    auto checkDevNull = [&](const char* when) {
        struct stat after {};
        ASSERT_EQ(::lstat("/dev/null", &after), 0) << when;
        EXPECT_TRUE(S_ISCHR(after.st_mode)) << when << ": /dev/null is no longer a character device";
        EXPECT_EQ(after.st_rdev, before.st_rdev) << when;
        EXPECT_EQ(after.st_ino, before.st_ino) << when;
        EXPECT_EQ(listDir("/dev"), devEntries) << when << ": a file was left in /dev";
    };

    {
        AtomicFile file("/dev/null", "cannot write '/dev/null'");
        EXPECT_TRUE(file.writesThrough());
        EXPECT_EQ(file.tempPath(), "/dev/null");
        ASSERT_GE(file.descriptor(), 0);
        writeAll(file.descriptor(), std::string(100000, 'x'));
        EXPECT_NO_THROW(file.sync());
        EXPECT_NO_THROW(file.commit());
    }
    checkDevNull("after a commit");

    // A failure or a missing commit never removes /dev/null.
    {
        AtomicFile file("/dev/null", "cannot write '/dev/null'");
        EXPECT_THROW(file.fail("test failure"), IoError);
    }
    checkDevNull("after fail()");
    {
        AtomicFile file("/dev/null", "cannot write '/dev/null'");
        writeAll(file.descriptor(), "abc");
    }
    checkDevNull("after no commit");

    // Through a link: the link stays, /dev/null stays.
    const fs::path dir = scratchDir("atomic_devnull");
    const fs::path link = dir / "discard.vdb";
    fs::create_symlink("/dev/null", link);
    writeAtomically(link.string(), "data");
    EXPECT_TRUE(fs::is_symlink(link));
    EXPECT_EQ(fs::read_symlink(link), "/dev/null");
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"discard.vdb"});
    checkDevNull("through a link");
}

TEST(AtomicFile, FollowsSymbolicLinks)
{
    const fs::path dir = scratchDir("atomic_links");
    fs::create_directory(dir / "real");
    std::ofstream(dir / "real" / "m.vdb") << "old";
    fs::create_symlink("real/m.vdb", dir / "link.vdb");
    fs::create_symlink("link.vdb", dir / "link2.vdb"); // a chain

    writeAtomically((dir / "link2.vdb").string(), "new");
    EXPECT_TRUE(fs::is_symlink(dir / "link.vdb"));
    EXPECT_TRUE(fs::is_symlink(dir / "link2.vdb"));
    EXPECT_EQ(readText(dir / "real" / "m.vdb"), "new");
    EXPECT_EQ(listDir(dir / "real"), std::vector<std::string>{"m.vdb"});
    {
        AtomicFile file((dir / "link.vdb").string(), "x");
        EXPECT_EQ(fs::path(file.tempPath()).parent_path(), dir / "real"); // next to the target
    }

    // A dangling link: the file it names is created, the link stays.
    fs::create_symlink("real/made.vdb", dir / "dangling.vdb");
    writeAtomically((dir / "dangling.vdb").string(), "made");
    EXPECT_TRUE(fs::is_symlink(dir / "dangling.vdb"));
    EXPECT_EQ(readText(dir / "real" / "made.vdb"), "made");

    // A loop is refused with a message.
    fs::create_symlink("loop2.vdb", dir / "loop1.vdb");
    fs::create_symlink("loop1.vdb", dir / "loop2.vdb");
    const std::string msg = messageOf((dir / "loop1.vdb").string());
    EXPECT_NE(msg.find("too many levels of symbolic links"), std::string::npos) << msg;
}

TEST(AtomicFile, RemovesStaleTemporaryFilesOfDeadProcessesOnly)
{
    using levelforge::detail::temporaryFileName;
    const fs::path dir = scratchDir("atomic_stale");
    const long dead = deadPid();
    ASSERT_GT(dead, 0);
    const long self = long(::getpid());
    const long parent = long(::getppid());

    const std::string staleDead = temporaryFileName("out.vdb", dead, 0x0123abcd);
    const std::string staleDead2 = temporaryFileName("out.vdb", dead, 0x99999999);
    const std::vector<std::string> kept = {
        temporaryFileName("out.vdb", self, 0x0123abcd),   // ours: live
        temporaryFileName("out.vdb", parent, 0x1123abcd), // live
        temporaryFileName("out.vdb", 1, 0x2123abcd),      // init: live (or EPERM)
        temporaryFileName("other.vdb", dead, 0x0123abcd), // another target
        "out.vdb." + std::to_string(dead) + "-0123abcd.tmp",   // not hidden: not ours
        ".out.vdb." + std::to_string(dead) + "-0123ABCD.tmp",  // not the exact pattern
        ".out.vdb." + std::to_string(dead) + "-0123abcd.tmp~", // not the exact pattern
        "out.vdb.bak",
    };
    touch(dir / staleDead);
    touch(dir / staleDead2);
    for (const std::string& name : kept) touch(dir / name);
    // A directory with a stale name is not removed either.
    const std::string staleDir = temporaryFileName("out.vdb", dead, 0x44444444);
    fs::create_directory(dir / staleDir);

    writeAtomically((dir / "out.vdb").string(), "fresh");

    std::vector<std::string> expected = kept;
    expected.push_back("out.vdb");
    expected.push_back(staleDir);
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(listDir(dir), expected);
    EXPECT_EQ(readText(dir / "out.vdb"), "fresh");

    // The function itself: nothing more to remove.
    EXPECT_EQ(levelforge::detail::removeStaleTemporaryFiles((dir / "out.vdb").string()), 0);
    touch(dir / staleDead);
    EXPECT_EQ(levelforge::detail::removeStaleTemporaryFiles((dir / "out.vdb").string()), 1);
    EXPECT_FALSE(fs::exists(dir / staleDead));
}

TEST(AtomicFile, AbortedWritesLeaveNothing)
{
    AbortGuard guard;
    const fs::path dir = scratchDir("atomic_abort");
    const std::string target = (dir / "out.vdb").string();

    // Aborted before the write starts.
    levelforge::detail::abortWrites();
    EXPECT_TRUE(levelforge::detail::writesAborted());
    EXPECT_THROW(AtomicFile(target, "cannot write"), InterruptedError);
    EXPECT_TRUE(fs::is_empty(dir));
    EXPECT_THROW(AtomicFile("/dev/null", "cannot write"), InterruptedError);
    levelforge::detail::clearAbortedWrites();

    // Aborted during the write: commit() removes the temporary file, the old file stays.
    writeAtomically(target, "old");
    {
        AtomicFile file(target, "cannot write");
        writeAll(file.descriptor(), "new");
        levelforge::detail::abortWrites();
        try {
            file.commit();
            ADD_FAILURE() << "commit() after abortWrites() succeeded";
        } catch (const InterruptedError& e) {
            EXPECT_NE(std::string(e.what()).find("interrupted"), std::string::npos) << e.what();
        }
        EXPECT_FALSE(fs::exists(file.tempPath()));
    }
    EXPECT_EQ(readText(target), "old");
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.vdb"});
}

TEST(AtomicFile, RemoveLiveTemporaryFilesUnlinksThemForASignalHandler)
{
    // removeLiveTemporaryFiles() takes its table entries for good (the process is meant to end
    // right after), so it runs in a child process, as the CLI's signal handler would.
    const fs::path dir = scratchDir("atomic_live");
    const std::string target = (dir / "out.vdb").string();
    std::ofstream(target) << "old";
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
        int code = 0;
        try {
            AtomicFile file(target, "cannot write");
            if (::write(file.descriptor(), "partial", 7) != 7) code = 1;
            const std::string tmp = file.tempPath();
            if (::access(tmp.c_str(), F_OK) != 0) code = 2;
            if (levelforge::detail::removeLiveTemporaryFiles() < 1) code = 3;
            if (::access(tmp.c_str(), F_OK) == 0) code = 4;
            if (levelforge::detail::removeLiveTemporaryFiles() != 0) code = 5; // taken for good
        } catch (...) {
            code = 6;
        }
        ::_exit(code); // as the signal handler does
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 0);
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.vdb"});
    EXPECT_EQ(readText(target), "old");
}
